// The four real bitewise services in this process, for tests of their
// clients: the BanditService on a SQLite file in a temporary directory, the
// PerceptionService with its weight-free default featurizer, the
// HapticService with the shipped HapticNet, and the RobotService on the
// simulated world (its Net F/T box streams over real UDP on loopback). Each
// listens on its own loopback port. Calls can be made to fail on purpose
// through FaultInjector, a client interceptor on the channels this hands
// out: a named method answers a chosen status without reaching its server,
// as a service that is down or refusing would.
#ifndef BITEWISE_TESTS_MEAL_FOUR_SERVICES_H_
#define BITEWISE_TESTS_MEAL_FOUR_SERVICES_H_

#include <grpcpp/channel.h>

#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "clients/meal/service_clients.h"
#include "gtest/gtest.h"

namespace bitewise::testing {

// Which calls fail. Thread-safe.
class FaultInjector {
 public:
  // Calls of `method` ("/bitewise.v1.BanditService/Update") answer `status`
  // from now on, without reaching the server.
  void Fail(const std::string& method, absl::Status status);
  void Clear();
  // The status a call of `method` answers, or OK to let it through.
  absl::Status For(const std::string& method) const;

 private:
  mutable absl::Mutex mu_;
  std::vector<std::pair<std::string, absl::Status>> faults_
      ABSL_GUARDED_BY(mu_);
};

struct FourServicesOptions {
  // The simulated plate: one item per food; empty is the paper's eight.
  std::vector<std::string> foods;
  uint64_t seed = 7;
  // Arm speeds multiplied by this outside the descent (whose speed the
  // simulated force traces are modelled at), so tests wait less.
  double transit_speedup = 4.0;
  // Negative: the HapticService has no familiarity model. Otherwise it has
  // the shipped one with this threshold (1 flags nearly every trace
  // unfamiliar).
  double familiarity_threshold = -1.0;
};

class FourServices {
 public:
  static absl::StatusOr<std::unique_ptr<FourServices>> Start(
      const FourServicesOptions& options);
  ~FourServices();

  // Channels through the fault injector.
  const meals::ServiceChannels& channels() const { return channels_; }
  FaultInjector& faults() { return faults_; }
  std::string bandit_address() const;
  std::string perception_address() const;
  std::string haptic_address() const;
  std::string robot_address() const;
  const std::string& dir() const { return dir_; }
  // Items still on the simulated plate (an acquired item leaves it).
  int ItemsLeft() const;

 private:
  struct Impl;
  explicit FourServices(std::unique_ptr<Impl> impl);

  std::unique_ptr<Impl> impl_;
  FaultInjector faults_;
  meals::ServiceChannels channels_;
  std::string dir_;
};

// A test suite whose tests share one FourServices, started before the
// first test with `Suite::Options()` and stopped after the last.
template <typename Suite>
class SharedFourServicesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto started = FourServices::Start(Suite::Options());
    ASSERT_TRUE(started.ok()) << started.status();
    services_ = started->release();
  }
  static void TearDownTestSuite() {
    delete services_;
    services_ = nullptr;
  }

  static inline FourServices* services_ = nullptr;
};

}  // namespace bitewise::testing

#endif  // BITEWISE_TESTS_MEAL_FOUR_SERVICES_H_
