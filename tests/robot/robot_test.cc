// The acquisition loop (Robot) on the simulated backend, no gRPC: the real
// NetFtRdtClient reads the simulated box over loopback while the simulated
// arm moves. Covers a whole acquisition, the force-limit stop, Stop during
// an action, the F/T watchdog, and bad requests that must change nothing.
#include "services/robot/robot.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/steady_time.h"
#include "services/robot/backend.h"
#include "tests/robot/wait_for.h"

namespace bitewise::robot {
namespace {

using ::bitewise::testing::WaitFor;
using ::testing::AllOf;
using ::testing::ContainsRegex;
using ::testing::HasSubstr;

RobotBackendOptions SimOptions(std::vector<std::string> foods, uint64_t seed) {
  RobotBackendOptions options;
  options.kind = BackendKind::kSim;
  options.sim.seed = seed;
  options.sim.foods = std::move(foods);
  options.sim.box.rate_hz = 1000.0;
  options.ft.silence_timeout_s = 0.3;
  // Generous on a loaded 2-core machine; the watchdog test sets silence
  // that lasts until the arm has stopped anyway.
  options.acquisition.watchdog_timeout_s = 0.5;
  return options;
}

class RobotTest : public ::testing::Test {
 protected:
  void Start(std::vector<std::string> foods, uint64_t seed = 3) {
    StartWith(SimOptions(std::move(foods), seed));
  }
  void StartWith(const RobotBackendOptions& options) {
    auto backend = RobotBackend::Create(options);
    ASSERT_TRUE(backend.ok()) << backend.status();
    backend_ = std::move(backend).value();
  }
  void SetFault(const std::function<void(sim::SimNetFtFaults*)>& change) {
    sim::SimNetFtFaults faults = backend_->box()->faults();
    change(&faults);
    backend_->box()->SetFaults(faults);
  }

  AcquireTarget TargetOfItem(size_t i) {
    const sim::PlateScene scene = backend_->world()->scene();
    auto target = backend_->world()->TargetOf(scene.items.at(i).id);
    EXPECT_TRUE(target.has_value());
    return *target;
  }

  // Runs Acquire on another thread; `on_phase` is called (on that thread)
  // once when `phase` starts.
  std::future<absl::StatusOr<AcquireOutcome>> AcquireAsync(
      const AcquireTarget& target, std::string action, AcquirePhase phase,
      std::atomic<bool>* reached) {
    return std::async(std::launch::async, [=] {
      return backend_->robot().Acquire(target, action,
                                       [=](const AcquireProgressEvent& event) {
                                         if (event.phase == phase)
                                           *reached = true;
                                         return true;
                                       });
    });
  }

  bool ArmFrozen() {
    const ForkPose a = *backend_->sim_arm()->MeasuredPose();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const ForkPose b = *backend_->sim_arm()->MeasuredPose();
    return (a.p_TaskTip_m - b.p_TaskTip_m).norm() == 0.0;
  }

  std::unique_ptr<RobotBackend> backend_;
};

TEST_F(RobotTest, AcquireRunsEveryPhaseAndRecordsTheTrace) {
  Start({"strawberry", "banana"});
  const AcquireTarget target = TargetOfItem(0);
  const int items_before = backend_->items_left();
  std::vector<AcquirePhase> phases;
  absl::StatusOr<AcquireOutcome> outcome = backend_->robot().Acquire(
      target, "VS0", [&](const AcquireProgressEvent& event) {
        if (phases.empty() || phases.back() != event.phase) {
          phases.push_back(event.phase);
        }
        return true;
      });
  ASSERT_TRUE(outcome.ok()) << outcome.status();
  EXPECT_EQ(phases, (std::vector<AcquirePhase>{
                        AcquirePhase::kApproach, AcquirePhase::kOrient,
                        AcquirePhase::kDescend, AcquirePhase::kExtract,
                        AcquirePhase::kDone}));
  EXPECT_EQ(outcome->attempt.true_food_type, "strawberry");
  EXPECT_FALSE(outcome->attempt.decided_by_operator);
  // About a thousand samples a second throughout, in time order.
  ASSERT_GT(outcome->trace.size(), 0.7 * 1000 * outcome->duration_s);
  for (size_t i = 1; i < outcome->trace.size(); ++i) {
    ASSERT_GT(outcome->trace[i].t_s, outcome->trace[i - 1].t_s);
  }
  // Contact comes from the arm's motion: after the approach and the orient
  // (at least the standoff of 3 cm at 5 cm/s into the run), not before.
  EXPECT_GT(outcome->contact_time_s, 0.6);
  EXPECT_LT(outcome->contact_time_s, outcome->duration_s);
  EXPECT_FALSE(outcome->force_limit_reached);  // medium foods: < 5 N
  EXPECT_GT(outcome->peak_force_n, 1.5);
  EXPECT_LT(outcome->peak_force_n, 8.0);
  // The world decided; the plate agrees with the verdict.
  EXPECT_EQ(backend_->items_left(),
            items_before - (outcome->attempt.success ? 1 : 0));
  if (outcome->attempt.success) {
    // The strawberry hangs from the fork: grams, a few hundredths of a N.
    EXPECT_GT(outcome->static_load_n, 0.01);
  } else {
    EXPECT_NEAR(outcome->static_load_n, 0.0, 0.02);
  }
}

TEST_F(RobotTest, ADryRunFliesTheActionAboveTheFoodWithoutAnAttempt) {
  Start({"carrot"});
  const AcquisitionConfig& config = backend_->robot().config();
  const AcquireTarget target = TargetOfItem(0);
  const double item_top_z =
      ToTaskFrame(target, config.X_TaskCamera).p_TaskItem_m.z();
  std::vector<AcquirePhase> phases;
  AcquireOptions options;
  options.dry_run = true;
  absl::StatusOr<AcquireOutcome> dry = backend_->robot().Acquire(
      target, "TV0",
      [&](const AcquireProgressEvent& event) {
        if (phases.empty() || phases.back() != event.phase) {
          phases.push_back(event.phase);
        }
        return true;
      },
      options);
  ASSERT_TRUE(dry.ok()) << dry.status();
  EXPECT_TRUE(dry->dry_run);
  EXPECT_EQ(phases.size(), 5u);  // every phase, in the air
  // The deepest point is the clearance above the food: it was never
  // touched, and the plate still holds it.
  EXPECT_NEAR(dry->lowest_tip_z_m, item_top_z + config.dry_run_clearance_m,
              0.002);
  EXPECT_EQ(dry->contact_time_s, -1.0);
  EXPECT_LT(dry->peak_force_n, 0.5);
  EXPECT_EQ(backend_->items_left(), 1);
  EXPECT_FALSE(dry->attempt.success);
  // At a quarter of the speed: it takes longer than the real action.
  absl::StatusOr<AcquireOutcome> real =
      backend_->robot().Acquire(target, "TV0", nullptr);
  ASSERT_TRUE(real.ok()) << real.status();
  EXPECT_GT(dry->duration_s, 2.0 * real->duration_s);
}

TEST_F(RobotTest, AnyForceInADryRunStopsTheArm) {
  Start({"carrot"});
  AcquireOptions options;
  options.dry_run = true;
  bool pressed = false;
  absl::StatusOr<AcquireOutcome> dry = backend_->robot().Acquire(
      TargetOfItem(0), /*20 N; 10 N in a dry run*/ "TV0",
      [&](const AcquireProgressEvent& event) {
        if (event.phase == AcquirePhase::kOrient && !pressed) {
          pressed = true;
          SetFault([](sim::SimNetFtFaults* f) { f->press_n = 15.0; });
        }
        return true;
      },
      options);
  EXPECT_EQ(dry.status().code(), absl::StatusCode::kAborted);
  EXPECT_THAT(dry.status().message(),
              ::testing::HasSubstr("TV0 dry-run limit of 10.0 N"));
  EXPECT_TRUE(ArmFrozen());
  // Counted as a force-limit trip from the status's type, not its words.
  EXPECT_EQ(backend_->robot().Status().force_limit_trips, 1);
  EXPECT_EQ(backend_->robot().Status().acquisitions_failed, 1);
}

// The settling hold after the extraction is part of a dry run too: a force
// over the dry run's limit there stops it (the hold used to ignore it).
TEST_F(RobotTest, AForceWhileADryRunSettlesStopsIt) {
  Start({"carrot"});
  AcquireOptions options;
  options.dry_run = true;
  bool pressed = false;
  std::optional<ForkPose> last;
  absl::StatusOr<AcquireOutcome> dry = backend_->robot().Acquire(
      TargetOfItem(0), "TV0",
      [&](const AcquireProgressEvent& event) {
        if (event.phase != AcquirePhase::kExtract || pressed) return true;
        // The extraction's move is over when the arm stands still between
        // two reports: the settling hold has begun.
        const ForkPose now = *backend_->sim_arm()->MeasuredPose();
        if (last.has_value() &&
            (now.p_TaskTip_m - last->p_TaskTip_m).norm() < 1e-5) {
          pressed = true;
          SetFault([](sim::SimNetFtFaults* f) { f->press_n = 15.0; });
        }
        last = now;
        return true;
      },
      options);
  ASSERT_TRUE(pressed) << "the dry run ended before its settling hold";
  EXPECT_EQ(dry.status().code(), absl::StatusCode::kAborted) << dry.status();
  EXPECT_THAT(dry.status().message(),
              HasSubstr("TV0 dry-run limit of 10.0 N during extract"));
  EXPECT_TRUE(ArmFrozen());
}

TEST_F(RobotTest, TheSeedDecidesTheOutcome) {
  std::vector<bool> first, second;
  for (std::vector<bool>* run : {&first, &second}) {
    Start({"banana", "carrot"}, /*seed=*/11);
    for (size_t i = 0; i < 2; ++i) {
      absl::StatusOr<AcquireOutcome> outcome =
          backend_->robot().Acquire(TargetOfItem(0), "TA90", nullptr);
      ASSERT_TRUE(outcome.ok()) << outcome.status();
      run->push_back(outcome->attempt.success);
      if (backend_->items_left() == 0) break;
    }
    backend_.reset();
  }
  EXPECT_EQ(first, second);
}

TEST_F(RobotTest, ForceLimitStopsTheDescent) {
  // TA0 allows 10 N; hard foods push back with 10-18 N.
  Start({"carrot", "celery", "apple"}, /*seed=*/5);
  const sim::PlateScene scene = backend_->world()->scene();
  size_t hardest = 0;
  double hardest_n = 0.0;
  for (size_t i = 0; i < scene.items.size(); ++i) {
    const double peak =
        backend_->world()->ProfileOf(scene.items[i].id)->PeakForce();
    if (peak > hardest_n) {
      hardest_n = peak;
      hardest = i;
    }
  }
  ASSERT_GT(hardest_n, 12.0) << "seed 5 should give a stiff item";
  const double item_top_m = scene.items[hardest].height_m;
  absl::StatusOr<AcquireOutcome> outcome =
      backend_->robot().Acquire(TargetOfItem(hardest), "TA0", nullptr);
  ASSERT_TRUE(outcome.ok()) << outcome.status();
  EXPECT_TRUE(outcome->force_limit_reached);
  EXPECT_GE(outcome->peak_force_n, 10.0);
  // Stopped within a control period or two of crossing the limit.
  EXPECT_LT(outcome->peak_force_n, 15.0);
  // The arm stopped well short of the depth limit.
  const double depth_bottom_m =
      std::max(item_top_m - backend_->robot().config().depth_limit_m,
               backend_->robot().config().floor_z_m);
  EXPECT_GT(outcome->lowest_tip_z_m, depth_bottom_m + 0.002);
  EXPECT_LT(outcome->lowest_tip_z_m, item_top_m);
}

// A camera on the wrist sees the plate as X_TaskCamera says only from the
// viewing pose (home); a bite leaves the arm above the item. MoveToView
// brings it back under an acquisition's protection (the hardware backend
// does before each frame: a frame from where the bite ended was aimed at as
// if taken from home).
TEST_F(RobotTest, TheArmGoesBackToItsViewingPoseUnderProtection) {
  Start({"banana", "carrot"});  // one is left after the first bite
  const ForkPose home = *backend_->sim_arm()->MeasuredPose();
  absl::StatusOr<bool> there = backend_->robot().MoveToView();
  ASSERT_TRUE(there.ok()) << there.status();
  EXPECT_FALSE(*there);  // already home: nothing moves
  ASSERT_TRUE(backend_->robot().Acquire(TargetOfItem(0), "TA0", nullptr).ok());
  const ForkPose after_bite = *backend_->sim_arm()->MeasuredPose();
  EXPECT_GT((after_bite.p_TaskTip_m - home.p_TaskTip_m).norm(), 0.02);
  absl::StatusOr<bool> moved = backend_->robot().MoveToView();
  ASSERT_TRUE(moved.ok()) << moved.status();
  EXPECT_TRUE(*moved);
  const ForkPose back = *backend_->sim_arm()->MeasuredPose();
  EXPECT_LT((back.p_TaskTip_m - home.p_TaskTip_m).norm(), 0.01);
  EXPECT_NEAR(back.pitch_rad, home.pitch_rad, 0.05);
  EXPECT_EQ(backend_->robot().Status().busy_with, AcquirePhase::kIdle);

  // Stop halts the way back like any motion, and says so.
  ASSERT_TRUE(backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr).ok());
  auto returning = std::async(std::launch::async,
                              [&] { return backend_->robot().MoveToView(); });
  ASSERT_TRUE(WaitFor([&] {
    return backend_->robot().Status().busy_with == AcquirePhase::kApproach;
  }));
  ASSERT_TRUE(backend_->robot().Stop().ok());
  const absl::StatusOr<bool> stopped = returning.get();
  EXPECT_EQ(stopped.status().code(), absl::StatusCode::kAborted);
  EXPECT_THAT(stopped.status().message(),
              HasSubstr("The return to the viewing pose stopped by a Stop "
                        "request"));
  EXPECT_TRUE(ArmFrozen());
  // Nor does it go back by itself right after a Stop (one that reached an
  // idle robot just before a look was sent would otherwise be overridden).
  const absl::StatusOr<bool> held = backend_->robot().MoveToView();
  EXPECT_EQ(held.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(held.status().message(), HasSubstr("a Stop came"));
  EXPECT_TRUE(ArmFrozen());
  absl::SleepFor(absl::Seconds(1.1));

  // A silent sensor: the arm does not move at all.
  SetFault([](sim::SimNetFtFaults* f) { f->silent = true; });
  ASSERT_TRUE(WaitFor([&] { return !backend_->FtLive(); }));
  const int commands = backend_->sim_arm()->commands();
  const absl::StatusOr<bool> refused = backend_->robot().MoveToView();
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
}

TEST_F(RobotTest, StopHaltsWithinOneControlPeriod) {
  Start({"banana"});
  std::atomic<bool> descending{false};
  auto running =
      AcquireAsync(TargetOfItem(0), "TA0", AcquirePhase::kDescend, &descending);
  ASSERT_TRUE(WaitFor([&] { return descending.load(); }));
  const int commands_before = backend_->sim_arm()->commands();
  const double before_s = SteadyNowS();
  absl::StatusOr<bool> was_moving = backend_->robot().Stop();
  const double after_s = SteadyNowS();
  ASSERT_TRUE(was_moving.ok());
  EXPECT_TRUE(*was_moving);
  // Halted inside the Stop call, and not a single command after it.
  const double halt_s = backend_->sim_arm()->last_halt_s();
  EXPECT_GE(halt_s, before_s);
  EXPECT_LE(halt_s, after_s);
  const int commands_at_stop = backend_->sim_arm()->commands();
  EXPECT_LE(commands_at_stop - commands_before, 1);
  absl::StatusOr<AcquireOutcome> outcome = running.get();
  EXPECT_EQ(outcome.status().code(), absl::StatusCode::kAborted);
  EXPECT_THAT(outcome.status().message(),
              HasSubstr("stopped by a Stop request during descend"));
  EXPECT_EQ(backend_->sim_arm()->commands(), commands_at_stop);
  EXPECT_TRUE(ArmFrozen());
  // A Stop while idle changes nothing for the next acquisition.
  ASSERT_FALSE(*backend_->robot().Stop());
  EXPECT_TRUE(backend_->robot().Acquire(TargetOfItem(0), "TA0", nullptr).ok());
}

TEST_F(RobotTest, WatchdogStopsTheArmWhenTheSensorGoesSilent) {
  Start({"cantaloupe"});
  std::atomic<bool> descending{false};
  auto running =
      AcquireAsync(TargetOfItem(0), "VS0", AcquirePhase::kDescend, &descending);
  ASSERT_TRUE(WaitFor([&] { return descending.load(); }));
  sim::SimNetFtFaults faults;
  faults.silent = true;
  backend_->box()->SetFaults(faults);
  absl::StatusOr<AcquireOutcome> outcome = running.get();
  EXPECT_EQ(outcome.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(outcome.status().message(),
              HasSubstr("Net F/T sensor at 127.0.0.1:" +
                        std::to_string(backend_->box()->port())));
  EXPECT_THAT(outcome.status().message(), HasSubstr("watchdog 500 ms"));
  EXPECT_GE(backend_->sim_arm()->halts(), 1);
  EXPECT_TRUE(ArmFrozen());
  // No live stream: the next Acquire refuses before moving.
  const int commands = backend_->sim_arm()->commands();
  absl::Status refused =
      backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr).status();
  EXPECT_EQ(refused.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(refused.message(), HasSubstr("is silent"));
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
  backend_->box()->SetFaults(sim::SimNetFtFaults());
  ASSERT_TRUE(WaitFor([&] { return backend_->FtLive(); }));
  EXPECT_TRUE(backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr).ok());
}

// The force limit and the F/T counter: the safety cases, each asserting what
// the arm did. A box whose ft_sequence counts at another rate than the one
// configured once made every sample look stale, so the limit never saw a
// force; now the limit reads every sample received, and a counter that
// cannot be trusted stops the arm or keeps it from moving.

// A box counting once per record (1 kHz) against the configured 7 kHz.
RobotBackendOptions OncePerRecordBox(double expected_rate_hz) {
  RobotBackendOptions options = SimOptions({"banana"}, 3);
  options.sim.box.rate_hz = 1000.0;
  options.sim.box.internal_rate_hz = 1000.0;
  options.ft.counter.expected_rate_hz = expected_rate_hz;
  return options;
}

TEST_F(RobotTest, ACounterAtAnotherRateThanConfiguredNeverMovesTheArm) {
  StartWith(OncePerRecordBox(/*expected_rate_hz=*/7000.0));
  EXPECT_FALSE(backend_->FtLive());  // health: NOT_SERVING
  const RobotStatusInfo status = backend_->robot().Status();
  EXPECT_EQ(status.ft_health.counter.state, netft::CounterClockState::kFault);
  EXPECT_NEAR(status.ft_health.counter.measured_rate_hz, 1000.0, 100.0);
  const int commands = backend_->sim_arm()->commands();
  absl::Status refused =
      backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr).status();
  EXPECT_EQ(refused.code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(std::string(refused.message()),
              AllOf(HasSubstr("Net F/T sensor at 127.0.0.1:" +
                              std::to_string(backend_->box()->port())),
                    ContainsRegex("advances at (9[0-9][0-9]|1[01][0-9][0-9]) "
                                  "Hz but 7000 Hz is configured")));
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
  EXPECT_TRUE(ArmFrozen());
}

// Presses the fork with 40 N as the descent starts (VS0 allows 25 N) and
// checks that the arm went no further than one control period, two at most
// with the tick in flight, of descent past that point.
void ExpectAStepOfFortyNewtonsStopsTheDescent(RobotBackend* backend) {
  const AcquisitionConfig& config = backend->robot().config();
  double z_at_step_m = NAN;
  const auto target =
      backend->world()->TargetOf(backend->world()->scene().items.at(0).id);
  ASSERT_TRUE(target.has_value());
  absl::StatusOr<AcquireOutcome> outcome = backend->robot().Acquire(
      *target, "VS0", [&](const AcquireProgressEvent& event) {
        if (event.phase == AcquirePhase::kDescend && std::isnan(z_at_step_m)) {
          z_at_step_m = backend->sim_arm()->MeasuredPose()->p_TaskTip_m.z();
          sim::SimNetFtFaults faults = backend->box()->faults();
          faults.press_n = 40.0;
          backend->box()->SetFaults(faults);
          // Measure the robot's reaction, not the simulated box's
          // scheduling on a loaded machine: wait until the client has the
          // pressed sample before the descent's first tick.
          const double until_s = SteadyNowS() + 2.0;
          while (SteadyNowS() < until_s) {
            const std::optional<netft::FtSample> latest =
                backend->ft()->Latest();
            if (latest && latest->wrench.force_n[2] > 30.0) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
          }
        }
        return true;
      });
  backend->box()->SetFaults(sim::SimNetFtFaults());
  ASSERT_TRUE(outcome.ok()) << outcome.status();
  EXPECT_TRUE(outcome->force_limit_reached);
  EXPECT_GT(outcome->peak_force_n, 35.0);
  ASSERT_FALSE(std::isnan(z_at_step_m));
  EXPECT_GE(outcome->lowest_tip_z_m,
            z_at_step_m -
                2 * config.control_period_s * config.descend_speed_mps - 1e-9);
}

TEST_F(RobotTest, AFortyNewtonStepStopsTheDescentWithASevenKilohertzCounter) {
  Start({"banana"});
  ASSERT_TRUE(backend_->FtLive());
  ExpectAStepOfFortyNewtonsStopsTheDescent(backend_.get());
}

TEST_F(RobotTest, AFortyNewtonStepStopsTheDescentWithALearnedCounterRate) {
  StartWith(OncePerRecordBox(/*expected_rate_hz=*/0.0));  // learn it
  ASSERT_TRUE(WaitFor([&] { return backend_->FtLive(); }));
  EXPECT_NEAR(backend_->robot().Status().ft_health.counter.rate_hz, 1000.0,
              50.0);
  ExpectAStepOfFortyNewtonsStopsTheDescent(backend_.get());
}

TEST_F(RobotTest, ACounterThatJumpsMidDescentStopsTheArm) {
  Start({"banana"});
  std::atomic<bool> descending{false};
  auto running =
      AcquireAsync(TargetOfItem(0), "VS0", AcquirePhase::kDescend, &descending);
  ASSERT_TRUE(WaitFor([&] { return descending.load(); }));
  SetFault([](sim::SimNetFtFaults* f) { f->counter_offset_counts = 70000; });
  absl::StatusOr<AcquireOutcome> outcome = running.get();
  EXPECT_EQ(outcome.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(outcome.status().message(),
              AllOf(HasSubstr("Net F/T sensor at 127.0.0.1"),
                    HasSubstr("ft_sequence jumped by 70"),
                    HasSubstr("arm stopped during descend")));
  EXPECT_GE(backend_->sim_arm()->halts(), 1);
  EXPECT_TRUE(ArmFrozen());
  // Health drops, and comes back once a window of records is sane again
  // (the counter keeps its new offset and counts on at the right rate).
  EXPECT_FALSE(backend_->FtLive());
  ASSERT_TRUE(WaitFor([&] { return backend_->FtLive(); }));
  EXPECT_TRUE(backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr).ok());
}

TEST_F(RobotTest, ACounterThatStallsMidDescentStopsTheArm) {
  Start({"banana"});
  std::atomic<bool> descending{false};
  auto running =
      AcquireAsync(TargetOfItem(0), "VS0", AcquirePhase::kDescend, &descending);
  ASSERT_TRUE(WaitFor([&] { return descending.load(); }));
  SetFault([](sim::SimNetFtFaults* f) { f->counter_frozen = true; });
  absl::StatusOr<AcquireOutcome> outcome = running.get();
  EXPECT_EQ(outcome.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(outcome.status().message(), HasSubstr("ft_sequence stalled"));
  EXPECT_GE(backend_->sim_arm()->halts(), 1);
  EXPECT_TRUE(ArmFrozen());
  const int commands = backend_->sim_arm()->commands();
  EXPECT_FALSE(backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr).ok());
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
}

TEST_F(RobotTest, AFaultStatusWordMidDescentStopsTheArm) {
  Start({"banana"});
  std::atomic<bool> descending{false};
  auto running =
      AcquireAsync(TargetOfItem(0), "VS0", AcquirePhase::kDescend, &descending);
  ASSERT_TRUE(WaitFor([&] { return descending.load(); }));
  SetFault([](sim::SimNetFtFaults* f) { f->status_word = 0x00010000; });
  absl::StatusOr<AcquireOutcome> outcome = running.get();
  EXPECT_EQ(outcome.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(outcome.status().message(),
              AllOf(HasSubstr("reports fault status 0x00010000"),
                    HasSubstr("arm stopped during descend")));
  EXPECT_GE(backend_->sim_arm()->halts(), 1);
  EXPECT_TRUE(ArmFrozen());
  EXPECT_FALSE(backend_->FtLive());
}

// Gauges that stop being read while the box streams on (clean status word,
// advancing counter, the last readings repeated exactly) leave the arm with
// no force protection: the descent stops, health drops and the message
// names the sensor; health returns once the readings move again. Before
// the fix a bite went on in this state, and the HapticService then only
// found "no contact".
TEST_F(RobotTest, FrozenReadingsMidDescentStopTheArm) {
  Start({"banana"});
  ASSERT_TRUE(backend_->FtLive());
  std::atomic<bool> descending{false};
  auto running =
      AcquireAsync(TargetOfItem(0), "VS0", AcquirePhase::kDescend, &descending);
  ASSERT_TRUE(WaitFor([&] { return descending.load(); }));
  SetFault([](sim::SimNetFtFaults* f) { f->readings_frozen = true; });
  absl::StatusOr<AcquireOutcome> outcome = running.get();
  EXPECT_EQ(outcome.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(outcome.status().message(),
              AllOf(HasSubstr("Net F/T sensor at 127.0.0.1"),
                    HasSubstr("all six readings identical"),
                    HasSubstr("no force protection"),
                    HasSubstr("arm stopped during descend")));
  EXPECT_GE(backend_->sim_arm()->halts(), 1);
  EXPECT_TRUE(ArmFrozen());
  EXPECT_FALSE(backend_->FtLive());
  EXPECT_GE(backend_->robot().Status().ft_health.readings_unchanged_s, 0.1);
  // Nothing moves while they stay frozen.
  const int commands = backend_->sim_arm()->commands();
  absl::StatusOr<AcquireOutcome> refused =
      backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(refused.status().message(), HasSubstr("all six readings"));
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
  SetFault([](sim::SimNetFtFaults* f) { f->readings_frozen = false; });
  ASSERT_TRUE(WaitFor([&] { return backend_->FtLive(); }));
  EXPECT_LT(backend_->robot().Status().ft_health.readings_unchanged_s, 0.1);
}

TEST_F(RobotTest, ACounterThatWrapsIsNotAFault) {
  RobotBackendOptions options = SimOptions({"banana", "kiwi"}, 3);
  // 2^32 is reached about a second after the box boots: mid-acquisition.
  options.sim.box.ft_sequence_at_boot = 0xFFFFFFFFu - 7000u;
  StartWith(options);
  for (int i = 0; i < 2; ++i) {
    absl::StatusOr<AcquireOutcome> outcome =
        backend_->robot().Acquire(TargetOfItem(0), "VS0", nullptr);
    ASSERT_TRUE(outcome.ok()) << outcome.status();
    ASSERT_GT(outcome->trace.size(), 0.7 * 1000 * outcome->duration_s);
    for (size_t k = 1; k < outcome->trace.size(); ++k) {
      ASSERT_GT(outcome->trace[k].t_s, outcome->trace[k - 1].t_s);
    }
    if (backend_->items_left() == 0) break;
  }
  EXPECT_EQ(backend_->robot().Status().ft_health.counter.state,
            netft::CounterClockState::kOk);
}

// A control loop held up past its period is counted (the metric
// bitewise_robot_control_overruns_total): here the progress callback, which
// runs on the control thread, stalls it once for five periods.
TEST_F(RobotTest, AStalledControlLoopIsCountedAsAnOverrun) {
  Start({"banana"});
  EXPECT_EQ(backend_->robot().Status().control_overruns, 0);
  bool stalled = false;
  absl::StatusOr<AcquireOutcome> outcome = backend_->robot().Acquire(
      TargetOfItem(0), "VS0", [&](const AcquireProgressEvent& event) {
        if (event.phase == AcquirePhase::kApproach && !stalled) {
          stalled = true;
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        return true;
      });
  ASSERT_TRUE(outcome.ok()) << outcome.status();
  ASSERT_TRUE(stalled);
  EXPECT_GE(backend_->robot().Status().control_overruns, 1);
}

TEST_F(RobotTest, OneAcquisitionAtATime) {
  Start({"kiwi"});
  std::atomic<bool> approaching{false};
  auto running = AcquireAsync(TargetOfItem(0), "TA0", AcquirePhase::kApproach,
                              &approaching);
  ASSERT_TRUE(WaitFor([&] { return approaching.load(); }));
  absl::Status second =
      backend_->robot().Acquire(TargetOfItem(0), "TA0", nullptr).status();
  EXPECT_EQ(second.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(second.message(),
              HasSubstr("the arm is moving (an Acquire, phase approach)"));
  absl::Status tare = backend_->robot().Tare();
  EXPECT_EQ(tare.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(tare.message(), HasSubstr("while the arm moves (an Acquire)"));
  // Nor is the arm sent to its viewing pose, nor a picture taken, while it
  // moves (it may pass home).
  const absl::StatusOr<bool> view = backend_->robot().MoveToView();
  EXPECT_EQ(view.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(view.status().message(),
              HasSubstr("no picture is taken from a moving arm"));
  EXPECT_EQ(backend_->robot().CheckAtView().code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_TRUE(running.get().ok());
  EXPECT_EQ(backend_->box()->counters().bias_commands, 0u);
  EXPECT_TRUE(backend_->robot().Tare().ok());
  EXPECT_TRUE(
      WaitFor([&] { return backend_->box()->counters().bias_commands == 1; }));
}

TEST_F(RobotTest, BadRequestsAreRejectedAndMoveNothing) {
  Start({"grape"});
  const int commands = backend_->sim_arm()->commands();
  const AcquireTarget good = TargetOfItem(0);
  for (const char* action : {"", "VS45", "vs0"}) {
    absl::Status status =
        backend_->robot().Acquire(good, action, nullptr).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(), HasSubstr("no skewering action is named"));
  }
  AcquireTarget far = good;
  far.p_CameraItem_m.x() = 0.4;
  absl::Status status = backend_->robot().Acquire(far, "VS0", nullptr).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("outside the workspace"));
  AcquireTarget deep = good;
  deep.p_CameraItem_m.z() = 0.5;  // 15 cm below the plate
  status = backend_->robot().Acquire(deep, "VS0", nullptr).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  AcquireTarget nan = good;
  nan.major_axis_angle_rad = std::nan("");
  status = backend_->robot().Acquire(nan, "VS0", nullptr).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("finite"));
  EXPECT_EQ(backend_->sim_arm()->commands(), commands);
  EXPECT_EQ(backend_->items_left(), 1);
}

}  // namespace
}  // namespace bitewise::robot
