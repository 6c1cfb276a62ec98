// Robot: executes the six skewering actions as parameterised motions on an
// Arm at the control rate (100 Hz) while recording the Forque's F/T stream,
// and enforces the safety rules: the action's force limit ends the descent
// (and, reached while approaching or orienting, a collision, aborts),
// Stop() halts the arm within one control period, and a watchdog halts it
// when the F/T stream goes silent. One acquisition at a time.
//
// Backend-independent: the same code drives the JACO2 with a real Net F/T
// box and the simulated arm with the simulated box. No gRPC here.
//
// Thread-safe. Acquire() blocks for the whole motion (seconds); Stop(),
// Tare() and Status() may be called concurrently from other threads.
#ifndef BITEWISE_SERVICES_ROBOT_ROBOT_H_
#define BITEWISE_SERVICES_ROBOT_ROBOT_H_

#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "services/domain/wrench.h"
#include "services/robot/actions.h"
#include "services/robot/arm.h"
#include "services/robot/ft_recorder.h"
#include "services/robot/netft/netft_rdt_client.h"
#include "services/robot/success_judge.h"

namespace bitewise::robot {

struct AcquisitionConfig {
  double control_period_s = 0.01;  // 100 Hz, the JACO2's command rate
  // Pose of the camera frame (scene.h convention) in the task frame at
  // capture time.
  RigidTransform X_TaskCamera = CameraLookingDown(0.35);
  Workspace workspace;
  // Approach: to this height above the item's top surface.
  double standoff_m = 0.03;
  double approach_speed_mps = 0.15;
  double orient_rate_radps = 1.5;
  // Descent: straight down at this speed (the force-trace model's reference
  // insertion speed in simulation), to depth_limit_m below the item's top
  // but never below floor_z_m in the task frame.
  double descend_speed_mps = 0.05;
  double depth_limit_m = 0.015;
  double floor_z_m = 0.002;
  // Extraction: straight up to this height above the standoff.
  double extract_speed_mps = 0.08;
  double lift_m = 0.05;
  // Held still after the lift; the static load is averaged over the last
  // static_window_s of it.
  double settle_s = 0.3;
  double static_window_s = 0.2;
  // The unloaded reading is averaged over this long before moving.
  double baseline_s = 0.1;
  // |F - baseline| above this is contact (for contact_time_s).
  double contact_threshold_n = 0.5;
  // The arm stops when no F/T sample arrived for this long.
  double watchdog_timeout_s = 0.1;
  // Progress reports per second while moving.
  double progress_rate_hz = 10.0;
  // A dry run (AcquireOptions::dry_run) flies the action in the air: the
  // descent ends this far above the item's top, every speed is scaled by
  // dry_run_speed_scale and the action's force limit by
  // dry_run_force_scale, and any force above that limit in any phase is a
  // collision (nothing should be touched).
  double dry_run_clearance_m = 0.03;
  double dry_run_speed_scale = 0.25;
  double dry_run_force_scale = 0.5;
};

struct AcquireOptions {
  // For hardware bring-up: the whole motion, slower, above the food;
  // success is not judged (the outcome says dry_run) and nothing is
  // counted as an attempt.
  bool dry_run = false;
};

enum class AcquirePhase {
  kIdle,
  kApproach,
  kOrient,
  kDescend,
  kExtract,
  kDone
};
const char* AcquirePhaseName(AcquirePhase phase);

struct AcquireProgressEvent {
  AcquirePhase phase = AcquirePhase::kIdle;
  double elapsed_s = 0.0;
  double force_n = 0.0;  // |F - baseline| of the latest sample
};

// Return false to cancel the acquisition (e.g. the caller went away).
using AcquireProgressCallback =
    std::function<bool(const AcquireProgressEvent& event)>;

struct AcquireOutcome {
  AttemptOutcome attempt;
  // Every sample, raw (not baseline-removed).
  std::vector<domain::TimedWrench> trace;
  double peak_force_n = 0.0;  // max |F - baseline|
  bool force_limit_reached = false;
  double contact_time_s = -1.0;  // -1: never touched anything
  double static_load_n = 0.0;
  double duration_s = 0.0;
  // Lowest tip height reached, task frame.
  double lowest_tip_z_m = 0.0;
  // The motion was a dry run: attempt.success is false and means nothing.
  bool dry_run = false;
};

struct RobotStatusInfo {
  bool arm_ready = false;
  std::string arm_name;
  netft::StreamHealth ft_health;
  netft::RdtStats ft_stats;
  std::string ft_name;
  AcquirePhase busy_with = AcquirePhase::kIdle;
  // Since the Robot was made (for metrics): acquisitions run (dry runs
  // included), those that ended in an error, and force-limit trips (the
  // descent stopped at the limit, or a motion aborted by it).
  int64_t acquisitions = 0;
  int64_t acquisitions_failed = 0;
  int64_t force_limit_trips = 0;
  // Control periods that began after their tick had passed: the previous
  // period's work, or a stall of the machine, took longer than the period.
  int64_t control_overruns = 0;
};

class Robot {
 public:
  // `arm`, `ft` and `judge` must outlive the Robot.
  Robot(Arm* arm, netft::NetFtRdtClient* ft, SuccessJudge* judge,
        const AcquisitionConfig& config);

  // Runs the action named `action` on `target`; `on_progress` (may be empty)
  // hears each phase start and progress_rate_hz reports. Errors, all leaving
  // the arm halted if it had moved:
  //  - INVALID_ARGUMENT: no action has that name, target not finite or outside
  //    the workspace (nothing moves);
  //  - FAILED_PRECONDITION: another acquisition is running (nothing moves);
  //  - UNAVAILABLE naming the F/T sensor: no live F/T stream at the start,
  //    or silent for longer than the watchdog during the motion;
  //  - ABORTED: Stop() was called, or the force limit was exceeded outside
  //    the descent (a collision);
  //  - CANCELLED: `on_progress` returned false;
  //  - errors of the Arm, passed through.
  // With options.dry_run, also ABORTED when any force above the reduced
  // limit is felt in any phase (the fork should touch nothing).
  absl::StatusOr<AcquireOutcome> Acquire(
      const AcquireTarget& target, std::string_view action,
      const AcquireProgressCallback& on_progress,
      const AcquireOptions& options = {});

  // The pose the arm comes to rest in (two readings 0.1 s apart within 1 mm
  // and 0.01 rad; UNAVAILABLE if it does not within `settle_timeout_s`)
  // becomes its viewing pose: where a camera on the wrist sees the plate as
  // X_TaskCamera says (the backend records it once the arm is home), and is
  // returned. The arm's errors, prefixed "recording the viewing pose".
  absl::StatusOr<ForkPose> RecordViewPose(double settle_timeout_s = 10.0);

  // Moves the arm back to its viewing pose in a straight line at the
  // approach speed, under the protection of an acquisition (a live F/T
  // stream, its watchdog, a collision limit of the gentlest action's
  // force, Stop); returns whether it had to move (false: it is there, within
  // 1 cm and 0.05 rad). FAILED_PRECONDITION before RecordViewPose, while an
  // acquisition runs, or when the arm ends more than that away; the errors
  // of Acquire otherwise, the arm halted.
  absl::StatusOr<bool> MoveToView();

  // OK while no motion runs and the arm is at its viewing pose (as
  // MoveToView measures it); FAILED_PRECONDITION saying where it is
  // otherwise. For a picture taken there: asked after it was taken.
  absl::Status CheckAtView();

  // Halts the arm now (within the control period in which it is called: no
  // further command is sent after it returns) and ends a running
  // acquisition with ABORTED. Returns whether an acquisition was running.
  absl::StatusOr<bool> Stop();

  // Software bias of the F/T sensor. FAILED_PRECONDITION during an
  // acquisition (the baseline would jump mid-trace).
  absl::Status Tare();

  // With `ask_arm` false, arm_ready is not measured (no call to the arm: a
  // USB round trip on the JACO2, under the lock its control loop takes
  // every period): for metrics scraped while the arm works.
  RobotStatusInfo Status(bool ask_arm = true);

  // OK while the arm answers: asked at most once a second, and not while
  // an acquisition runs (which watches the arm itself); else the arm's
  // error, naming it.
  absl::Status ArmReadiness();

  const AcquisitionConfig& config() const { return config_; }

 private:
  class Run;

  Arm* const arm_;
  netft::NetFtRdtClient* const ft_;
  SuccessJudge* const judge_;
  const AcquisitionConfig config_;

  // Guards the busy flag and the stop request; held while commanding the arm
  // so that no command can follow a Halt() issued by Stop().
  std::mutex mu_;
  std::condition_variable stop_cv_;
  bool busy_ = false;
  bool stop_requested_ = false;
  AcquirePhase phase_ = AcquirePhase::kIdle;
  int64_t acquisitions_ = 0;
  int64_t acquisitions_failed_ = 0;
  int64_t force_limit_trips_ = 0;
  std::atomic<int64_t> control_overruns_{0};
  std::optional<ForkPose> view_pose_;  // RecordViewPose's
  const char* motion_ = "";            // what busy_ is for, for messages
  double last_stop_s_ = -1e9;          // when Stop was last called (SteadyNowS)
  // ArmReadiness's last answer and when it was asked.
  absl::Status arm_readiness_;
  double arm_checked_s_ = -1e9;
};

}  // namespace bitewise::robot

#endif  // BITEWISE_SERVICES_ROBOT_ROBOT_H_
