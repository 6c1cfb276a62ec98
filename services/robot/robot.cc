#include "services/robot/robot.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "absl/strings/cord.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/string_view.h"
#include "services/common/status_macros.h"
#include "services/domain/steady_time.h"

namespace bitewise::robot {
namespace {

using Clock = std::chrono::steady_clock;

// Marks the ABORTED status of a motion halted by the force limit, so the
// trip is counted from the status's type, not from its wording.
constexpr char kForceLimitTripPayload[] = "type.bitewise/robot.ForceLimitTrip";

ForkPose Interpolate(const ForkPose& a, const ForkPose& b, double s) {
  ForkPose out;
  out.p_TaskTip_m = a.p_TaskTip_m + s * (b.p_TaskTip_m - a.p_TaskTip_m);
  out.yaw_rad = a.yaw_rad + s * (b.yaw_rad - a.yaw_rad);
  out.pitch_rad = a.pitch_rad + s * (b.pitch_rad - a.pitch_rad);
  return out;
}

}  // namespace

const char* AcquirePhaseName(AcquirePhase phase) {
  switch (phase) {
    case AcquirePhase::kIdle:
      return "idle";
    case AcquirePhase::kApproach:
      return "approach";
    case AcquirePhase::kOrient:
      return "orient";
    case AcquirePhase::kDescend:
      return "descend";
    case AcquirePhase::kExtract:
      return "extract";
    case AcquirePhase::kDone:
      return "done";
  }
  return "unknown";
}

// One acquisition: the 100 Hz loop and everything it records.
class Robot::Run {
 public:
  Run(Robot* robot, const ActionSpec& action, const TaskTarget& target,
      const AcquireProgressCallback& on_progress, bool dry_run)
      : robot_(robot),
        config_(dry_run ? DryRunConfig(robot->config_) : robot->config_),
        action_(dry_run ? DryRunAction(action, robot->config_) : action),
        target_(dry_run ? Raised(target, robot->config_) : target),
        on_progress_(on_progress),
        dry_run_(dry_run),
        ft_(config_.contact_threshold_n) {}

  absl::Status Execute() {
    start_s_ = SteadyNowS();
    MeasureBaseline();
    ASSIGN_OR_RETURN(setpoint_, robot_->arm_->MeasuredPose());
    lowest_z_ = setpoint_.p_TaskTip_m.z();
    next_tick_ = Clock::now();

    const Eigen::Vector3d& item = target_.p_TaskItem_m;
    ForkPose standoff = setpoint_;
    standoff.p_TaskTip_m =
        Eigen::Vector3d(item.x(), item.y(), item.z() + config_.standoff_m);
    bool force_stop = false;
    RETURN_IF_ERROR(MoveTo(AcquirePhase::kApproach, standoff,
                           config_.approach_speed_mps, &force_stop));

    ForkPose oriented = standoff;
    const double yaw = ForkYaw(action_, target_.major_axis_yaw_rad);
    // The shortest way round: the same yaw modulo 2 pi.
    oriented.yaw_rad =
        setpoint_.yaw_rad + std::remainder(yaw - setpoint_.yaw_rad, 2 * M_PI);
    oriented.pitch_rad = action_.pitch_rad;
    RETURN_IF_ERROR(MoveTo(AcquirePhase::kOrient, oriented,
                           config_.approach_speed_mps, &force_stop));

    ForkPose bottom = oriented;
    bottom.p_TaskTip_m.z() =
        std::max(item.z() - config_.depth_limit_m, config_.floor_z_m);
    RETURN_IF_ERROR(MoveTo(AcquirePhase::kDescend, bottom,
                           config_.descend_speed_mps, &force_stop));
    outcome_.force_limit_reached = force_stop;
    if (force_stop) {
      // Continue from where the arm actually stopped.
      ASSIGN_OR_RETURN(setpoint_, robot_->arm_->MeasuredPose());
    }
    absl::StatusOr<ForkPose> measured = robot_->arm_->MeasuredPose();
    lowest_z_ = std::min(lowest_z_, measured.ok() ? measured->p_TaskTip_m.z()
                                                  : setpoint_.p_TaskTip_m.z());

    ForkPose lifted = setpoint_;
    lifted.p_TaskTip_m.z() = item.z() + config_.standoff_m + config_.lift_m;
    RETURN_IF_ERROR(MoveTo(AcquirePhase::kExtract, lifted,
                           config_.extract_speed_mps, &force_stop));
    const double settle_start_s = SteadyNowS() - start_s_;
    RETURN_IF_ERROR(Hold(AcquirePhase::kExtract, config_.settle_s));

    outcome_.duration_s = SteadyNowS() - start_s_;
    outcome_.static_load_n = ft_.StaticLoad(std::max(
        settle_start_s, outcome_.duration_s - config_.static_window_s));
    if (dry_run_) {
      outcome_.dry_run = true;
    } else {
      outcome_.attempt = robot_->judge_->EndAttempt(outcome_.static_load_n);
    }
    outcome_.lowest_tip_z_m = lowest_z_;
    outcome_.peak_force_n = ft_.peak_force_n();
    outcome_.contact_time_s = ft_.contact_time_s();
    outcome_.trace = ft_.TakeTrace();
    Report(AcquirePhase::kDone, /*force=*/true);
    return absl::OkStatus();
  }

  AcquireOutcome TakeOutcome() { return std::move(outcome_); }

  // Back to `goal` (the viewing pose) at the approach speed, guarded by
  // action_'s limit as a collision anywhere on the way.
  absl::Status ReturnTo(ForkPose goal) {
    what_ = "The return to the viewing pose";
    start_s_ = SteadyNowS();
    MeasureBaseline();
    ASSIGN_OR_RETURN(setpoint_, robot_->arm_->MeasuredPose());
    lowest_z_ = setpoint_.p_TaskTip_m.z();
    next_tick_ = Clock::now();
    // The shortest way round: the same yaw modulo 2 pi.
    goal.yaw_rad = setpoint_.yaw_rad +
                   std::remainder(goal.yaw_rad - setpoint_.yaw_rad, 2 * M_PI);
    bool force_stop = false;
    RETURN_IF_ERROR(MoveTo(AcquirePhase::kApproach, goal,
                           config_.approach_speed_mps, &force_stop));
    // Held there while the arm's position control takes up what it lags.
    return Hold(AcquirePhase::kApproach, config_.settle_s);
  }

 private:
  static AcquisitionConfig DryRunConfig(const AcquisitionConfig& c) {
    AcquisitionConfig slow = c;
    slow.approach_speed_mps *= c.dry_run_speed_scale;
    slow.orient_rate_radps *= c.dry_run_speed_scale;
    slow.descend_speed_mps *= c.dry_run_speed_scale;
    slow.extract_speed_mps *= c.dry_run_speed_scale;
    return slow;
  }
  // The whole motion lifted so that the deepest point of the descent is
  // dry_run_clearance_m above the item's top.
  static TaskTarget Raised(const TaskTarget& t, const AcquisitionConfig& c) {
    TaskTarget up = t;
    up.p_TaskItem_m.z() += c.dry_run_clearance_m + c.depth_limit_m;
    return up;
  }
  static ActionSpec DryRunAction(const ActionSpec& a,
                                 const AcquisitionConfig& c) {
    ActionSpec gentle = a;
    gentle.max_force_n *= c.dry_run_force_scale;
    return gentle;
  }

  // Moves in a straight line (and a linear change of yaw and pitch) at
  // `speed_mps` or orient_rate_radps, whichever takes longer. In the
  // descent, reaching the action's force limit halts the arm and ends the
  // motion early with *force_stop set.
  absl::Status MoveTo(AcquirePhase phase, const ForkPose& goal,
                      double speed_mps, bool* force_stop) {
    SetPhase(phase);
    const ForkPose start = setpoint_;
    const double distance_m = (goal.p_TaskTip_m - start.p_TaskTip_m).norm();
    const double angle_rad =
        std::max(std::abs(goal.yaw_rad - start.yaw_rad),
                 std::abs(goal.pitch_rad - start.pitch_rad));
    const double duration_s =
        std::max({distance_m / speed_mps, angle_rad / config_.orient_rate_radps,
                  config_.control_period_s});
    const int ticks = static_cast<int>(
        std::ceil(duration_s / config_.control_period_s - 1e-9));
    ForkVelocity velocity;
    velocity.v_TaskTip_mps =
        (goal.p_TaskTip_m - start.p_TaskTip_m) / duration_s;
    velocity.yaw_rate_radps = (goal.yaw_rad - start.yaw_rad) / duration_s;
    velocity.pitch_rate_radps = (goal.pitch_rad - start.pitch_rad) / duration_s;
    for (int k = 1; k <= ticks; ++k) {
      bool over_limit = false;
      RETURN_IF_ERROR(AwaitTick(phase, &over_limit));
      if (over_limit && LimitGuards(phase)) {
        return OverLimit(phase, force_stop);
      }
      ForkPose next = Interpolate(start, goal, static_cast<double>(k) / ticks);
      RETURN_IF_ERROR(Send(next, velocity));
    }
    // One more period so the arm reaches the last set point; a force over
    // the limit in it counts as in any other period of the phase.
    bool over_limit = false;
    RETURN_IF_ERROR(AwaitTick(phase, &over_limit));
    if (over_limit && LimitGuards(phase)) return OverLimit(phase, force_stop);
    return absl::OkStatus();
  }

  absl::Status Hold(AcquirePhase phase, double duration_s) {
    const int ticks = static_cast<int>(
        std::ceil(duration_s / config_.control_period_s - 1e-9));
    for (int k = 0; k < ticks; ++k) {
      bool over_limit = false;
      RETURN_IF_ERROR(AwaitTick(phase, &over_limit));
      if (over_limit && LimitGuards(phase)) {
        bool unused = false;
        return OverLimit(phase, &unused);
      }
      RETURN_IF_ERROR(Send(setpoint_, ForkVelocity()));
    }
    return absl::OkStatus();
  }

  // Extraction moves the tines out of the food, which unloads them: the
  // limit guards the pushing phases only, and every phase of a dry run,
  // which never means to touch anything.
  bool LimitGuards(AcquirePhase phase) const {
    return dry_run_ || phase != AcquirePhase::kExtract;
  }

  // The force went over the action's limit in `phase`: the arm halts. In a
  // real descent that is the food pushing back, and the descent ends there
  // (*force_stop); anywhere else, and in any phase of a dry run, it is a
  // collision, and the Acquire ends ABORTED.
  absl::Status OverLimit(AcquirePhase phase, bool* force_stop) {
    if (!dry_run_ && phase == AcquirePhase::kDescend) {
      if (absl::Status halted = HaltArm(); !halted.ok()) {
        return absl::Status(
            halted.code(),
            absl::StrFormat("force %.1f N reached the %s limit of %.1f N "
                            "during descend; halting the arm failed: %s",
                            ft_.last_force_n(), action_.name,
                            action_.max_force_n, halted.message()));
      }
      *force_stop = true;
      return absl::OkStatus();
    }
    absl::Status tripped = absl::AbortedError(absl::StrFormat(
        "force %.1f N exceeded the %s%s limit of %.1f N during %s "
        "(a collision?); arm halted",
        ft_.last_force_n(), action_.name, dry_run_ ? " dry-run" : "",
        action_.max_force_n, AcquirePhaseName(phase)));
    tripped.SetPayload(kForceLimitTripPayload, absl::Cord("1"));
    return HaltFor(std::move(tripped));
  }

  // Waits for the next control period (waking at once on Stop), then reads
  // the new F/T samples and applies the watchdog, the force limit and the
  // progress report.
  absl::Status AwaitTick(AcquirePhase phase, bool* over_limit) {
    const auto period = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(config_.control_period_s));
    next_tick_ += period;
    // Past its tick already: the last period's work (or a stall of the
    // machine) took longer than the period. Counted for the operator.
    const auto now = Clock::now();
    if (now > next_tick_) {
      robot_->control_overruns_.fetch_add(1, std::memory_order_relaxed);
    }
    // A late tick (a loaded machine) starts a new schedule rather than
    // firing a burst of catch-up commands.
    if (now > next_tick_ + period) next_tick_ = now;
    {
      std::unique_lock<std::mutex> lock(robot_->mu_);
      robot_->stop_cv_.wait_until(lock, next_tick_,
                                  [this] { return robot_->stop_requested_; });
      if (robot_->stop_requested_) return StoppedError();
    }
    Ingest();
    // The force limit first: it acts on every sample received, whatever
    // the state of the sensor's clock.
    *over_limit = ft_.TakeMaxForceSinceLastCall() >= action_.max_force_n;
    const netft::StreamHealth health = robot_->ft_->Health();
    if (health.silent_for_s > config_.watchdog_timeout_s) {
      return HaltFor(absl::UnavailableError(absl::StrFormat(
          "%s: no F/T data for %.0f ms during %s (watchdog %.0f ms); arm "
          "stopped",
          robot_->ft_->name(), 1e3 * health.silent_for_s,
          AcquirePhaseName(phase), 1e3 * config_.watchdog_timeout_s)));
    }
    // Wrong sensing stops the arm as surely as absent sensing: a fault
    // status word from the box, or a counter that cannot be trusted.
    if (absl::Status sane = robot_->ft_->CheckDuringMotion(); !sane.ok()) {
      return HaltFor(absl::UnavailableError(absl::StrCat(
          sane.message(), "; arm stopped during ", AcquirePhaseName(phase))));
    }
    if (!Report(phase, /*force=*/false)) {
      return HaltFor(absl::CancelledError("Acquire cancelled by the caller"));
    }
    return absl::OkStatus();
  }

  absl::Status Send(const ForkPose& setpoint, const ForkVelocity& velocity) {
    std::lock_guard<std::mutex> lock(robot_->mu_);
    if (robot_->stop_requested_) return StoppedError();
    setpoint_ = setpoint;
    lowest_z_ = std::min(lowest_z_, setpoint.p_TaskTip_m.z());
    return robot_->arm_->Command(setpoint, velocity);
  }

  absl::Status HaltArm() {
    std::lock_guard<std::mutex> lock(robot_->mu_);
    return robot_->arm_->Halt();
  }

  // Halts the arm and returns `why`, the reason it was halted. If the halt
  // fails too, the reason (the sensor, the limit) still comes first, with
  // its code and payloads, and the halt's error is added to its message.
  absl::Status HaltFor(absl::Status why) {
    const absl::Status halted = HaltArm();
    if (halted.ok()) return why;
    absl::Status both(why.code(),
                      absl::StrCat(why.message(), "; halting the arm failed: ",
                                   halted.message()));
    why.ForEachPayload([&both](absl::string_view url, const absl::Cord& p) {
      both.SetPayload(url, p);
    });
    return both;
  }

  absl::Status StoppedError() const {
    return absl::AbortedError(absl::StrFormat(
        "%s stopped by a Stop request during %s, %.2f s in; arm halted", what_,
        AcquirePhaseName(phase_), SteadyNowS() - start_s_));
  }

  void SetPhase(AcquirePhase phase) {
    phase_ = phase;
    {
      std::lock_guard<std::mutex> lock(robot_->mu_);
      robot_->phase_ = phase;
    }
    Report(phase, /*force=*/true);
  }

  // Returns false if the caller cancelled.
  bool Report(AcquirePhase phase, bool force) {
    const double now_s = SteadyNowS();
    if (!force && now_s - last_report_s_ < 1.0 / config_.progress_rate_hz) {
      return true;
    }
    last_report_s_ = now_s;
    outcome_.duration_s = now_s - start_s_;
    if (!on_progress_) return true;
    AcquireProgressEvent event;
    event.phase = phase;
    event.elapsed_s = now_s - start_s_;
    event.force_n = ft_.last_force_n();
    return on_progress_(event);
  }

  // The baseline from the samples of the last few seconds; every sample
  // after these belongs to the acquisition.
  void MeasureBaseline() {
    std::vector<netft::FtSample> recent;
    std::optional<netft::FtSample> latest = robot_->ft_->Latest();
    if (latest) {
      const uint64_t back = 8192;
      next_index_ = robot_->ft_->SamplesSince(
          latest->index >= back ? latest->index - back : 0, &recent);
    }
    ft_.Start(recent, start_s_, config_.baseline_s);
  }

  void Ingest() {
    std::vector<netft::FtSample> fresh;
    next_index_ = robot_->ft_->SamplesSince(next_index_, &fresh);
    ft_.Add(fresh);
  }

  Robot* const robot_;
  const AcquisitionConfig config_;  // scaled for a dry run
  const ActionSpec action_;         // its limit scaled for a dry run
  const TaskTarget target_;
  const AcquireProgressCallback& on_progress_;
  const bool dry_run_;

  const char* what_ = "Acquire";  // the motion, for messages
  AcquireOutcome outcome_;
  AcquirePhase phase_ = AcquirePhase::kIdle;
  ForkPose setpoint_;
  double lowest_z_ = 0.0;
  double start_s_ = 0.0;
  Clock::time_point next_tick_;
  FtRecorder ft_;
  uint64_t next_index_ = 0;
  double last_report_s_ = -1e9;
};

Robot::Robot(Arm* arm, netft::NetFtRdtClient* ft, SuccessJudge* judge,
             const AcquisitionConfig& config)
    : arm_(arm), ft_(ft), judge_(judge), config_(config) {}

absl::StatusOr<AcquireOutcome> Robot::Acquire(
    const AcquireTarget& target, std::string_view action_name,
    const AcquireProgressCallback& on_progress, const AcquireOptions& options) {
  ASSIGN_OR_RETURN(const ActionSpec action, FindAction(action_name));
  const TaskTarget task_target = ToTaskFrame(target, config_.X_TaskCamera);
  RETURN_IF_ERROR(CheckInWorkspace(task_target, config_.workspace));
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (busy_) {
      return absl::FailedPreconditionError(
          absl::StrCat("the arm is moving (", motion_, ", phase ",
                       AcquirePhaseName(phase_), "); Stop it or wait"));
    }
    busy_ = true;
    motion_ = "an Acquire";
    // A Stop sent while idle must not cancel the next acquisition.
    stop_requested_ = false;
    phase_ = AcquirePhase::kApproach;
  }
  absl::Status live = ft_->CheckLive();
  absl::StatusOr<AcquireOutcome> result;
  if (!live.ok()) {
    result = live;
  } else {
    // A dry run is no attempt: the judge (and the simulated world) never
    // hears of it.
    if (!options.dry_run) judge_->BeginAttempt(action);
    Run run(this, action, task_target, on_progress, options.dry_run);
    absl::Status status = run.Execute();
    if (status.ok()) {
      result = run.TakeOutcome();
    } else {
      {
        std::lock_guard<std::mutex> lock(mu_);
        arm_->Halt().IgnoreError();  // the error being returned says more
      }
      if (!options.dry_run) judge_->AbortAttempt();
      result = status;
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  busy_ = false;
  phase_ = AcquirePhase::kIdle;
  ++acquisitions_;
  if (!result.ok()) ++acquisitions_failed_;
  if ((result.ok() && result->force_limit_reached) ||
      result.status().GetPayload(kForceLimitTripPayload).has_value()) {
    ++force_limit_trips_;
  }
  return result;
}

namespace {

// How far `pose` is from `goal`: metres and the larger angle.
std::pair<double, double> Distance(const ForkPose& pose, const ForkPose& goal) {
  return {
      (pose.p_TaskTip_m - goal.p_TaskTip_m).norm(),
      std::max(std::abs(std::remainder(pose.yaw_rad - goal.yaw_rad, 2 * M_PI)),
               std::abs(pose.pitch_rad - goal.pitch_rad))};
}

constexpr double kViewToleranceM = 0.01;
constexpr double kViewToleranceRad = 0.05;

// OK when `pose` is within `share` of the viewing tolerance (1 cm, 0.05
// rad) of `view`; else FAILED_PRECONDITION saying how far it is, then `what`.
absl::Status NearView(const ForkPose& pose, const ForkPose& view, double share,
                      absl::string_view what) {
  const auto [metres, radians] = Distance(pose, view);
  if (metres <= share * kViewToleranceM &&
      radians <= share * kViewToleranceRad) {
    return absl::OkStatus();
  }
  return absl::FailedPreconditionError(absl::StrFormat(
      "the arm was %.1f cm and %.2f rad from its viewing pose %s", 100 * metres,
      radians, what));
}
// How long a Stop keeps MoveToView from moving the arm.
constexpr double kStopHoldsS = 1.0;

}  // namespace

absl::StatusOr<ForkPose> Robot::RecordViewPose(double settle_timeout_s) {
  // The pose once the arm has come to rest (homing may still be ending):
  // two readings 0.1 s apart within 1 mm and 0.01 rad.
  const double deadline_s = SteadyNowS() + settle_timeout_s;
  absl::StatusOr<ForkPose> last = arm_->MeasuredPose();
  while (true) {
    if (!last.ok()) {
      return absl::Status(last.status().code(),
                          absl::StrCat("recording the viewing pose: ",
                                       last.status().message()));
    }
    absl::SleepFor(absl::Milliseconds(100));
    absl::StatusOr<ForkPose> next = arm_->MeasuredPose();
    if (next.ok()) {
      const auto [metres, radians] = Distance(*next, *last);
      if (metres <= 0.001 && radians <= 0.01) {
        std::lock_guard<std::mutex> lock(mu_);
        view_pose_ = *next;
        return *next;
      }
      if (SteadyNowS() > deadline_s) {
        return absl::UnavailableError(absl::StrFormat(
            "recording the viewing pose: the arm did not come to rest within "
            "%.0f s of homing (it moved %.1f mm in 0.1 s)",
            settle_timeout_s, 1000 * metres));
      }
    }
    last = next;
  }
}

absl::StatusOr<bool> Robot::MoveToView() {
  ForkPose view;
  {
    // Busy first: while another motion runs the arm is no place to take a
    // picture from, even where it passes home.
    std::lock_guard<std::mutex> lock(mu_);
    if (!view_pose_.has_value()) {
      return absl::FailedPreconditionError(
          "the arm's viewing pose was never recorded");
    }
    if (busy_) {
      return absl::FailedPreconditionError(absl::StrCat(
          "the arm is moving (", motion_, ", phase ", AcquirePhaseName(phase_),
          "); no picture is taken from a moving arm"));
    }
    // A Stop that reached an idle robot just before this call (the person
    // pressed STOP as the look was being asked for) is not overridden by a
    // motion nobody asked for since.
    const double since_stop_s = SteadyNowS() - last_stop_s_;
    if (since_stop_s < kStopHoldsS) {
      return absl::FailedPreconditionError(absl::StrFormat(
          "a Stop came %.0f ms ago: the arm is not moved back to its viewing "
          "pose within %.0f s of one; look again",
          1e3 * since_stop_s, kStopHoldsS));
    }
    view = *view_pose_;
    busy_ = true;
    motion_ = "the return to the viewing pose";
    stop_requested_ = false;
  }
  absl::StatusOr<ForkPose> now = arm_->MeasuredPose();
  if (now.ok()) {
    // Half the tolerance CheckAtView allows: an arm left at its edge is
    // moved, not refused after the picture.
    if (NearView(*now, view, 0.5, "").ok()) {
      std::lock_guard<std::mutex> lock(mu_);
      busy_ = false;
      return false;
    }
    std::lock_guard<std::mutex> lock(mu_);
    phase_ = AcquirePhase::kApproach;
  }
  absl::Status status = now.ok() ? ft_->CheckLive() : now.status();
  if (status.ok()) {
    // Nothing should be touched on the way: the gentlest action's force is
    // the collision limit.
    ActionSpec guard;
    guard.name = "return-to-view";
    guard.max_force_n = std::numeric_limits<double>::infinity();
    for (const ActionSpec& a : SkeweringActions()) {
      guard.max_force_n = std::min(guard.max_force_n, a.max_force_n);
    }
    static const AcquireProgressCallback kNoProgress;
    Run run(this, guard, TaskTarget{}, kNoProgress, /*dry_run=*/false);
    status = run.ReturnTo(view);
  }
  if (status.ok()) {
    absl::StatusOr<ForkPose> reached = arm_->MeasuredPose();
    status = reached.status();
    if (reached.ok()) {
      status = NearView(*reached, view, 1.0,
                        "after going back; the camera's view is known only "
                        "there");
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (!status.ok() && now.ok()) {
    arm_->Halt().IgnoreError();  // the error says more
  }
  busy_ = false;
  phase_ = AcquirePhase::kIdle;
  if (status.GetPayload(kForceLimitTripPayload).has_value()) {
    ++force_limit_trips_;
  }
  if (!status.ok()) return status;
  return true;
}

absl::Status Robot::CheckAtView() {
  ForkPose view;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (busy_) {
      return absl::FailedPreconditionError(absl::StrCat(
          "the arm moved while the picture was taken (", motion_, ")"));
    }
    if (!view_pose_.has_value()) {
      return absl::FailedPreconditionError(
          "the arm's viewing pose was never recorded");
    }
    view = *view_pose_;
  }
  ASSIGN_OR_RETURN(const ForkPose now, arm_->MeasuredPose());
  return NearView(now, view, 1.0, "when the picture was taken; look again");
}

absl::StatusOr<bool> Robot::Stop() {
  bool was_running = false;
  absl::Status halted;
  {
    std::lock_guard<std::mutex> lock(mu_);
    was_running = busy_;
    if (busy_) stop_requested_ = true;
    last_stop_s_ = SteadyNowS();
    halted = arm_->Halt();
  }
  stop_cv_.notify_all();
  if (!halted.ok()) return halted;
  return was_running;
}

absl::Status Robot::Tare() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (busy_) {
      return absl::FailedPreconditionError(
          absl::StrCat("cannot tare while the arm moves (", motion_,
                       "): the baseline would jump mid-trace"));
    }
  }
  return ft_->Bias();
}

absl::Status Robot::ArmReadiness() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    const double now_s = SteadyNowS();
    if (busy_ || now_s - arm_checked_s_ < 1.0) return arm_readiness_;
    arm_checked_s_ = now_s;
  }
  const absl::Status pose = arm_->MeasuredPose().status();
  absl::Status readiness =
      pose.ok()
          ? absl::OkStatus()
          : absl::Status(pose.code(),
                         absl::StrCat("arm ", arm_->name(),
                                      " does not answer: ", pose.message()));
  std::lock_guard<std::mutex> lock(mu_);
  arm_readiness_ = readiness;
  return readiness;
}

RobotStatusInfo Robot::Status(bool ask_arm) {
  RobotStatusInfo info;
  info.arm_name = arm_->name();
  info.arm_ready = ask_arm && arm_->MeasuredPose().ok();
  info.ft_health = ft_->Health();
  info.ft_stats = ft_->stats();
  info.ft_name = ft_->name();
  std::lock_guard<std::mutex> lock(mu_);
  info.busy_with = phase_;
  info.acquisitions = acquisitions_;
  info.acquisitions_failed = acquisitions_failed_;
  info.force_limit_trips = force_limit_trips_;
  info.control_overruns = control_overruns_.load(std::memory_order_relaxed);
  return info;
}

}  // namespace bitewise::robot
