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
// Verified against the published Kinova JACO2 SDK 1.5.1 headers (KinovaTypes.h
// and Kinova.API.UsbCommandLayerUbuntu.h / ...EthCommandLayerUbuntu.h, as
// shipped in Kinova's kinova-ros driver): every struct below has the same
// fields, in the same order, with the same types; the enum values used are
// the SDK's; and the entry points are extern "C" functions taking
// (CartesianPosition&) or (TrajectoryPoint) by value, or nothing. The
// static_asserts at the end pin the sizes and offsets that follow from the
// published layout (all 4-byte members, no padding), so a change here that
// would break the ABI fails to compile. The fake SDK that the tests build
// (tests/robot/fake_kinova_sdk.cc) includes this header, so the tests check
// the driver; these asserts check the layout.
#ifndef BITEWISE_SERVICES_ROBOT_JACO2_KINOVA_TYPES_H_
#define BITEWISE_SERVICES_ROBOT_JACO2_KINOVA_TYPES_H_

#include <cstddef>

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

// The published layout, pinned: sizes and offsets in bytes.
static_assert(sizeof(PositionType) == 4 && sizeof(HandModeType) == 4,
              "SDK enums are int-sized");
static_assert(sizeof(CartesianInfo) == 24, "6 floats");
static_assert(sizeof(AngularInfo) == 28, "7 floats: MAXACTUATORNUMBER is 7");
static_assert(sizeof(FingersPosition) == 12, "3 floats");
static_assert(sizeof(CartesianPosition) == 36, "CartesianInfo + fingers");
static_assert(offsetof(CartesianPosition, Fingers) == 24);
static_assert(sizeof(UserPosition) == 76);
static_assert(offsetof(UserPosition, Type) == 0);
static_assert(offsetof(UserPosition, Delay) == 4);
static_assert(offsetof(UserPosition, CartesianPosition) == 8);
static_assert(offsetof(UserPosition, Actuators) == 32);
static_assert(offsetof(UserPosition, HandMode) == 60);
static_assert(offsetof(UserPosition, Fingers) == 64);
static_assert(sizeof(Limitation) == 36, "9 floats");
static_assert(sizeof(TrajectoryPoint) == 120);
static_assert(offsetof(TrajectoryPoint, Position) == 0);
static_assert(offsetof(TrajectoryPoint, LimitationsActive) == 76);
static_assert(offsetof(TrajectoryPoint, SynchroType) == 80);
static_assert(offsetof(TrajectoryPoint, Limitations) == 84);
// POSITION_TYPE and HAND_MODE values as the SDK numbers them.
static_assert(kCartesianPosition == 1 && kAngularPosition == 2 &&
              kCartesianVelocity == 7 && kAngularVelocity == 8);
static_assert(kHandNoMovement == 0 && kPositionMode == 1 && kVelocityMode == 2);

}  // namespace bitewise::jaco2::kinova

#endif  // BITEWISE_SERVICES_ROBOT_JACO2_KINOVA_TYPES_H_
