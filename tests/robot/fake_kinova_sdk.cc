// A fake Kinova JACO2 SDK shared library for the Jaco2Arm tests: the
// hardware boundary, so a fake is legitimate here. It exports the SDK
// functions the driver maps (with BITEWISE_FAKE_KINOVA_PREFIX, "" for the
// USB variant or "Ethernet_"), records every call, and integrates
// Cartesian velocity commands over one 10 ms period so poses move. The test
// reads the record through FakeKinova_* functions found with dlsym.
#include <cstring>
#include <mutex>
#include <string>

#include "services/robot/jaco2/kinova_types.h"

#ifndef BITEWISE_FAKE_KINOVA_PREFIX
#error "define BITEWISE_FAKE_KINOVA_PREFIX"
#endif
#define FAKE_CONCAT_INNER(a, b) a##b
#define FAKE_CONCAT(a, b) FAKE_CONCAT_INNER(a, b)
#define SDK(name) FAKE_CONCAT(BITEWISE_FAKE_KINOVA_PREFIX, name)

namespace kinova = bitewise::jaco2::kinova;

namespace {

std::mutex mu;
std::string calls;             // "InitAPI;StartControlAPI;..."
std::string failing;           // a function that returns an error
kinova::CartesianInfo pose{};  // current end-effector pose
kinova::TrajectoryPoint last_point{};
int points = 0;

int Record(const char* name) {
  calls += name;
  calls += ';';
  return failing == name ? 1015 : kinova::kNoErrorKinova;
}

}  // namespace

extern "C" {

__attribute__((visibility("default"))) int SDK(InitAPI)() {
  std::lock_guard<std::mutex> lock(mu);
  pose = {0.0f, -0.45f, 0.10f, 3.14159265f, 0.0f, 0.0f};
  return Record("InitAPI");
}
__attribute__((visibility("default"))) int SDK(CloseAPI)() {
  std::lock_guard<std::mutex> lock(mu);
  return Record("CloseAPI");
}
__attribute__((visibility("default"))) int SDK(StartControlAPI)() {
  std::lock_guard<std::mutex> lock(mu);
  return Record("StartControlAPI");
}
__attribute__((visibility("default"))) int SDK(MoveHome)() {
  std::lock_guard<std::mutex> lock(mu);
  pose = {0.0f, -0.45f, 0.10f, 3.14159265f, 0.0f, 0.0f};
  return Record("MoveHome");
}
__attribute__((visibility("default"))) int SDK(SetCartesianControl)() {
  std::lock_guard<std::mutex> lock(mu);
  return Record("SetCartesianControl");
}
__attribute__((visibility("default"))) int SDK(GetCartesianPosition)(
    kinova::CartesianPosition* response) {
  std::lock_guard<std::mutex> lock(mu);
  response->Coordinates = pose;
  return Record("GetCartesianPosition");
}
__attribute__((visibility("default"))) int SDK(GetCartesianForce)(
    kinova::CartesianPosition* response) {
  std::lock_guard<std::mutex> lock(mu);
  response->Coordinates = {1.0f, -2.0f, 3.5f, 0.25f, 0.0f, -0.5f};
  return Record("GetCartesianForce");
}
__attribute__((visibility("default"))) int SDK(SendBasicTrajectory)(
    kinova::TrajectoryPoint point) {
  std::lock_guard<std::mutex> lock(mu);
  last_point = point;
  ++points;
  if (point.Position.Type == kinova::kCartesianVelocity) {
    const kinova::CartesianInfo& v = point.Position.CartesianPosition;
    pose.X += 0.01f * v.X;
    pose.Y += 0.01f * v.Y;
    pose.Z += 0.01f * v.Z;
    pose.ThetaX += 0.01f * v.ThetaX;
    pose.ThetaZ += 0.01f * v.ThetaZ;
  }
  return Record("SendBasicTrajectory");
}
__attribute__((visibility("default"))) int SDK(EraseAllTrajectories)() {
  std::lock_guard<std::mutex> lock(mu);
  return Record("EraseAllTrajectories");
}

// Test access (unprefixed in both variants).
__attribute__((visibility("default"))) void FakeKinova_Calls(char* out,
                                                             int size) {
  std::lock_guard<std::mutex> lock(mu);
  std::strncpy(out, calls.c_str(), size - 1);
  out[size - 1] = '\0';
}
__attribute__((visibility("default"))) void FakeKinova_Reset(const char* fail) {
  std::lock_guard<std::mutex> lock(mu);
  calls.clear();
  failing = fail;
  points = 0;
  last_point = {};
}
// Moves the end effector by (dx, dy, dz) metres and tilts it by dthetax
// radians, as an arm left elsewhere (by a bite, or by hand).
__attribute__((visibility("default"))) void FakeKinova_Move(float dx, float dy,
                                                            float dz,
                                                            float dthetax) {
  std::lock_guard<std::mutex> lock(mu);
  pose.X += dx;
  pose.Y += dy;
  pose.Z += dz;
  pose.ThetaX += dthetax;
}
__attribute__((visibility("default"))) int FakeKinova_LastPoint(
    kinova::TrajectoryPoint* out) {
  std::lock_guard<std::mutex> lock(mu);
  *out = last_point;
  return points;
}

}  // extern "C"
