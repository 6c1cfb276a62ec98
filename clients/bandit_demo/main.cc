// bitewise-bandit-demo: simulated bites against a running BanditService.
//
// Until the perception, haptic and robot services exist, this client stands
// in for them with a small simulated plate: the eight unseen foods of the
// simulated world's food catalog, whose visual context is a noisy,
// food-specific feature vector, whose haptic category is observed by a noisy
// classifier, and whose success probability per action is the catalog's
// (the known optima of the paper (docs/robot.md)). Every bite goes through the
// real BanditService (Select, then Update) so that learning persists per
// user across meals.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/usage.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/time.h"
#include "bitewise/v1/bandit.grpc.pb.h"
#include "services/common/channel.h"
#include "services/common/flags_usage.h"
#include "services/common/grpc_status.h"
#include "services/domain/random.h"
#include "services/sim/food_catalog.h"

ABSL_FLAG(std::string, bandit, "127.0.0.1:50051", "BanditService address.");
ABSL_FLAG(std::string, user, "demo-user", "User whose model learns.");
ABSL_FLAG(std::string, meal, "meal-1", "Meal id recorded with each event.");
ABSL_FLAG(int, bites, 40,
          "Most bite attempts; the meal ends sooner when "
          "the plate is empty.");
ABSL_FLAG(uint64_t, seed, 1, "Seed of the simulated plate and outcomes.");
ABSL_FLAG(int, context_dim, 2048, "Visual context dimension for new users.");
ABSL_FLAG(std::string, posthoc, "logprob",
          "Post hoc context sent with each update: logprob or prob.");
ABSL_FLAG(std::string, learner, "posthoc",
          "Learner for a new user: posthoc, context_only or polinucb.");
ABSL_FLAG(std::string, tls_ca, "", "CA bundle of the server (turns on TLS).");
ABSL_FLAG(std::string, tls_cert, "", "Client certificate (mutual TLS).");
ABSL_FLAG(std::string, tls_key, "", "Client key (mutual TLS).");
ABSL_FLAG(int, deadline_ms, 5000, "Deadline of every call.");

namespace {

namespace v1 = bitewise::v1;

using bitewise::sim::FoodType;
using bitewise::sim::HapticCategory;

// Visual features: each food has a base appearance; each item adds
// within-type variation, and the features are non-negative like SPANet's
// post-ReLU activations.
class VisualModel {
 public:
  VisualModel(int foods, int dim, uint64_t seed) : dim_(dim) {
    std::mt19937_64 rng(seed);
    bitewise::random::Normal normal;
    for (int f = 0; f < foods; ++f) {
      std::vector<double> base(dim);
      for (double& x : base) x = 0.5 * normal(rng);
      bases_.push_back(base);
    }
  }

  std::vector<double> Observe(int food, std::mt19937_64& rng) const {
    bitewise::random::Normal normal(0.0, 0.35);
    std::vector<double> c(dim_);
    for (int i = 0; i < dim_; ++i) {
      c[i] = std::max(0.0, bases_[food][i] + normal(rng));
    }
    return c;
  }

 private:
  int dim_;
  std::vector<std::vector<double>> bases_;
};

// A noisy haptic classifier: softmax of a boosted true class plus noise.
std::vector<double> HapticProbabilities(HapticCategory category,
                                        std::mt19937_64& rng) {
  bitewise::random::Normal normal(0.0, 0.8);
  std::vector<double> logits(bitewise::sim::kHapticCategories);
  for (int k = 0; k < bitewise::sim::kHapticCategories; ++k)
    logits[k] = (k == static_cast<int>(category) ? 3.0 : 0.0) + normal(rng);
  const double top = *std::max_element(logits.begin(), logits.end());
  double sum = 0.0;
  for (double& l : logits) sum += (l = std::exp(l - top));
  for (double& l : logits) l /= sum;
  return logits;
}

std::unique_ptr<grpc::ClientContext> Context() {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(
      std::chrono::system_clock::now() +
      std::chrono::milliseconds(absl::GetFlag(FLAGS_deadline_ms)));
  return context;
}

int Fail(const char* what, const grpc::Status& status) {
  std::fprintf(stderr, "bitewise-bandit-demo: %s failed: %s\n", what,
               bitewise::FromGrpcStatus(status).ToString().c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "Runs simulated bites for one user against a BanditService.");
  bitewise::ShowOwnFlagsInHelp();
  bitewise::ParseFlagsOnly(argc, argv);
  const std::string posthoc_kind = absl::GetFlag(FLAGS_posthoc);
  if (posthoc_kind != "logprob" && posthoc_kind != "prob") {
    std::fprintf(stderr, "--posthoc: expected logprob or prob, got %s\n",
                 posthoc_kind.c_str());
    return 2;
  }

  bitewise::ChannelOptions channel_options;
  channel_options.tls_ca_file = absl::GetFlag(FLAGS_tls_ca);
  channel_options.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  channel_options.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  channel_options.max_attempts = 5;  // gRPC's retry policy on UNAVAILABLE
  channel_options.initial_backoff = absl::Milliseconds(200);
  auto channel =
      bitewise::MakeChannel(absl::GetFlag(FLAGS_bandit), channel_options);
  if (!channel.ok()) {
    std::fprintf(stderr, "bitewise-bandit-demo: %s\n",
                 channel.status().ToString().c_str());
    return 1;
  }
  auto stub = v1::BanditService::NewStub(*channel);
  const std::string user_id = absl::GetFlag(FLAGS_user);
  const std::string meal_id = absl::GetFlag(FLAGS_meal);

  // Find or create the user.
  v1::User user;
  {
    v1::GetUserRequest request;
    request.set_user_id(user_id);
    grpc::Status status = stub->GetUser(Context().get(), request, &user);
    if (status.error_code() == grpc::StatusCode::NOT_FOUND) {
      v1::CreateUserRequest create;
      create.set_user_id(user_id);
      create.mutable_config()->set_context_dim(
          absl::GetFlag(FLAGS_context_dim));
      create.mutable_config()->set_posthoc_dim(4);
      v1::Learner learner = v1::LEARNER_UNSPECIFIED;
      if (!v1::Learner_Parse(
              absl::AsciiStrToUpper("LEARNER_" + absl::GetFlag(FLAGS_learner)),
              &learner)) {
        std::fprintf(stderr, "--learner: unknown learner %s\n",
                     absl::GetFlag(FLAGS_learner).c_str());
        return 2;
      }
      create.mutable_config()->set_learner(learner);
      status = stub->CreateUser(Context().get(), create, &user);
      if (!status.ok()) return Fail("CreateUser", status);
      std::printf("new user %s (%s learner, d=%u)\n", user_id.c_str(),
                  v1::Learner_Name(user.config().learner()).c_str(),
                  user.config().context_dim());
    } else if (!status.ok()) {
      return Fail("GetUser", status);
    } else {
      std::printf("user %s continues from model version %lld\n",
                  user_id.c_str(),
                  static_cast<long long>(user.model_version()));
    }
  }
  const int dim = static_cast<int>(user.config().context_dim());
  const std::vector<const FoodType*> foods = bitewise::sim::UnseenFoods();
  const int num_foods = static_cast<int>(foods.size());
  // Appearance is fixed across meals.
  const VisualModel visual(num_foods, dim, 7);
  std::mt19937_64 rng(absl::GetFlag(FLAGS_seed) ^
                      std::hash<std::string>()(meal_id));

  std::vector<int> plate(num_foods);
  for (int f = 0; f < num_foods; ++f) plate[f] = f;
  std::shuffle(plate.begin(), plate.end(), rng);

  struct Tally {
    int attempts = 0;
    int failures = 0;
  };
  std::map<std::string, Tally> per_food;
  int attempts = 0, failures = 0;
  const int max_bites = absl::GetFlag(FLAGS_bites);
  std::printf("meal %s: %d items on the plate\n", meal_id.c_str(), num_foods);
  while (!plate.empty() && attempts < max_bites) {
    const int food = plate.back();
    const FoodType& spec = *foods[food];
    v1::SelectRequest select;
    select.set_user_id(user_id);
    select.set_meal_id(meal_id);
    select.set_item_label(spec.name);
    const std::vector<double> c = visual.Observe(food, rng);
    select.mutable_context()->Add(c.begin(), c.end());
    v1::SelectResponse chosen;
    grpc::Status status = stub->Select(Context().get(), select, &chosen);
    if (!status.ok()) return Fail("Select", status);

    absl::StatusOr<double> p_success =
        bitewise::sim::SuccessProbability(spec, chosen.action_name());
    if (!p_success.ok()) {
      std::fprintf(stderr, "Select: %s\n",
                   std::string(p_success.status().message()).c_str());
      return 1;
    }
    const bool success = bitewise::random::Canonical(rng) < *p_success;
    const std::vector<double> probs = HapticProbabilities(spec.category, rng);
    const int sensed = static_cast<int>(
        std::max_element(probs.begin(), probs.end()) - probs.begin());
    v1::UpdateRequest update;
    update.set_event_id(chosen.event_id());
    update.set_loss(success ? 0.0 : 1.0);
    for (double p : probs) {
      update.add_posthoc(posthoc_kind == "logprob" ? std::log(p) : p);
    }
    v1::UpdateResponse updated;
    status = stub->Update(Context().get(), update, &updated);
    if (!status.ok()) return Fail("Update", status);

    ++attempts;
    Tally& tally = per_food[spec.name];
    ++tally.attempts;
    if (!success) {
      ++failures;
      ++tally.failures;
    } else {
      plate.pop_back();
    }
    std::string lcbs;
    for (const v1::ActionEstimate& e : chosen.estimates()) {
      absl::StrAppend(&lcbs,
                      absl::StrFormat(" %s=%+.3f", e.action_name(), e.lcb()));
    }
    std::printf(
        "bite %2d  %-14s %-5s lcb[%s ]  %-7s haptic %s %.2f\n", attempts,
        spec.name.c_str(), chosen.action_name().c_str(), lcbs.c_str(),
        success ? "success" : "FAILED",
        bitewise::domain::HapticClassLabel(static_cast<HapticCategory>(sensed)),
        probs[sensed]);
    std::fflush(stdout);
  }

  std::printf("\nmeal %s summary: %d attempts, %d failures, %zu items left\n",
              meal_id.c_str(), attempts, failures, plate.size());
  std::printf("  %-14s %8s %8s\n", "food", "attempts", "failures");
  for (const auto& [name, tally] : per_food) {
    std::printf("  %-14s %8d %8d\n", name.c_str(), tally.attempts,
                tally.failures);
  }
  return 0;
}
