// The few Kinova JACO2 SDK types that Jaco2Arm passes across the SDK's C
// ABI, written from the public SDK documentation (KinovaTypes.h of SDK
// 1.5.x) because the SDK itself is not redistributable. Field order and
// types must match the SDK exactly; what was assumed:
//  - every scalar in these structs is a 32-bit float or a 32-bit int/enum;
//  - AngularInfo has seven actuators (the SDK sized it for the 7-DoF arm
//    and the 6-DoF arm leaves Actuator7 unused);
//  - functions return int, NO_ERROR_KINOVA (1) on success;
//  - functions taking a C++ reference in the SDK headers are called through
//    a pointer here, which is the same ABI.
// The fake SDK that the tests build (tests/robot/fake_kinova_sdk.cc)
// includes this header, so the tests check the driver, not this layout;
// check it against the vendor header on a machine that has the SDK.
#ifndef BITEWISE_SERVICES_ROBOT_JACO2_KINOVA_TYPES_H_
#define BITEWISE_SERVICES_ROBOT_JACO2_KINOVA_TYPES_H_

namespace bitewise::jaco2::kinova {

constexpr int kNoErrorKinova = 1;  // NO_ERROR_KINOVA

enum PositionType : int {
  kNoMovementPosition = 0,
  kCartesianPosition = 1,
  kAngularPosition = 2,
  kCartesianVelocity = 7,
  kAngularVelocity = 8,
};

enum HandModeType : int {
  kHandNoMovement = 0,
  kPositionMode = 1,
  kVelocityMode = 2,
};

// Metres and radians (Euler XYZ) for positions; m/s and rad/s for
// velocities.
struct CartesianInfo {
  float X, Y, Z, ThetaX, ThetaY, ThetaZ;
};

struct AngularInfo {
  float Actuator1, Actuator2, Actuator3, Actuator4, Actuator5, Actuator6,
      Actuator7;
};

struct FingersPosition {
  float Finger1, Finger2, Finger3;
};

struct CartesianPosition {
  CartesianInfo Coordinates;
  FingersPosition Fingers;
};

struct UserPosition {
  PositionType Type;
  float Delay;
  CartesianInfo CartesianPosition;
  AngularInfo Actuators;
  HandModeType HandMode;
  FingersPosition Fingers;
};

struct Limitation {
  float speedParameter1, speedParameter2, speedParameter3;
  float forceParameter1, forceParameter2, forceParameter3;
  float accelerationParameter1, accelerationParameter2, accelerationParameter3;
};

struct TrajectoryPoint {
  UserPosition Position;
  int LimitationsActive;
  int SynchroType;
  Limitation Limitations;
};

// The SDK entry points Jaco2Arm uses, as function pointer types.
using VoidFn = int (*)();
using GetCartesianFn = int (*)(CartesianPosition*);
using SendBasicTrajectoryFn = int (*)(TrajectoryPoint);

}  // namespace bitewise::jaco2::kinova

#endif  // BITEWISE_SERVICES_ROBOT_JACO2_KINOVA_TYPES_H_
