// The actions' geometry (services/robot/actions.h): the table the robot
// moves by is the domain's, an unknown action is refused naming the valid
// ones, and a camera target becomes a task-frame target and a fork yaw.
#include "services/robot/actions.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "services/domain/skewering_actions.h"

namespace bitewise::robot {
namespace {

using ::testing::HasSubstr;

TEST(ActionsTest, TheRobotsTableIsTheDomains) {
  const std::vector<ActionSpec>& actions = SkeweringActions();
  ASSERT_EQ(actions.size(), static_cast<size_t>(domain::kNumActions));
  for (int i = 0; i < domain::kNumActions; ++i) {
    const domain::SkeweringAction& want = domain::kSkeweringActions[i];
    EXPECT_EQ(actions[i].index, i);
    EXPECT_EQ(actions[i].name, want.name);
    EXPECT_EQ(actions[i].pitch_rad, want.pitch_rad);
    EXPECT_EQ(actions[i].roll_rad, want.roll_rad);
    EXPECT_EQ(actions[i].max_force_n, want.max_force_n);
    absl::StatusOr<ActionSpec> by_name = FindAction(want.name);
    ASSERT_TRUE(by_name.ok()) << by_name.status();
    EXPECT_EQ(by_name->index, i);
    absl::StatusOr<ActionSpec> from_wire = ActionFromWire(i);
    ASSERT_TRUE(from_wire.ok()) << from_wire.status();
    EXPECT_EQ(from_wire->name, want.name);
  }
}

TEST(ActionsTest, AnUnknownActionNamesTheValidOnes) {
  for (const char* bad : {"", "VS45", "vs0", "VS0 "}) {
    const absl::Status status = FindAction(bad).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(status.message(),
              absl::StrCat("no skewering action is named \"", bad,
                           "\": the actions are VS0, VS90, TV0, TV90, TA0, "
                           "TA90"));
  }
  for (int bad : {-1, domain::kNumActions, 1000}) {
    const absl::Status status = ActionFromWire(bad).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(),
                HasSubstr(absl::StrCat("action ", bad, " is out of range")));
    EXPECT_THAT(status.message(),
                HasSubstr("0..5 (VS0, VS90, TV0, TV90, TA0, TA90)"));
  }
}

TEST(ActionsTest, ACameraTargetBecomesATaskTargetAndAForkYaw) {
  const RigidTransform X_TaskCamera = CameraLookingDown(0.3);
  AcquireTarget target;
  // 2 cm right and 1 cm down in the image, on a plate 0.29 m away.
  target.p_CameraItem_m = Eigen::Vector3d(0.02, 0.01, 0.29);
  target.major_axis_angle_rad = M_PI / 6;  // towards image +y
  const TaskTarget task = ToTaskFrame(target, X_TaskCamera);
  EXPECT_NEAR(task.p_TaskItem_m.x(), 0.02, 1e-12);
  EXPECT_NEAR(task.p_TaskItem_m.y(), -0.01, 1e-12);  // image down is -y
  EXPECT_NEAR(task.p_TaskItem_m.z(), 0.01, 1e-12);   // 1 cm above the plate
  EXPECT_NEAR(task.major_axis_yaw_rad, -M_PI / 6, 1e-12);
  // VS0 follows the axis, VS90 turns a quarter from it; yaws stay in
  // [-pi, pi].
  EXPECT_NEAR(ForkYaw(*FindAction("VS0"), task.major_axis_yaw_rad), -M_PI / 6,
              1e-12);
  EXPECT_NEAR(ForkYaw(*FindAction("VS90"), task.major_axis_yaw_rad), M_PI / 3,
              1e-12);
  EXPECT_NEAR(ForkYaw(*FindAction("VS90"), 3.0), 3.0 + M_PI / 2 - 2 * M_PI,
              1e-12);
}

TEST(ActionsTest, TheWorkspaceRefusesNamingTheLimit) {
  const Workspace workspace;
  TaskTarget inside;
  inside.p_TaskItem_m = Eigen::Vector3d(0.05, -0.05, 0.02);
  EXPECT_TRUE(CheckInWorkspace(inside, workspace).ok());
  TaskTarget far = inside;
  far.p_TaskItem_m.x() = 0.2;
  EXPECT_THAT(CheckInWorkspace(far, workspace).message(),
              HasSubstr("from the plate centre"));
  EXPECT_THAT(CheckInWorkspace(far, workspace).message(),
              HasSubstr("limit 0.150 m"));
  TaskTarget high = inside;
  high.p_TaskItem_m.z() = 0.2;
  EXPECT_THAT(CheckInWorkspace(high, workspace).message(),
              HasSubstr("above the plate, allowed -0.010..0.100 m"));
  TaskTarget nan = inside;
  nan.major_axis_yaw_rad = std::nan("");
  EXPECT_EQ(CheckInWorkspace(nan, workspace).code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(CheckInWorkspace(nan, workspace).message(),
              HasSubstr("must be finite"));
}

}  // namespace
}  // namespace bitewise::robot
