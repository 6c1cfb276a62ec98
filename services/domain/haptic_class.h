// The four haptic classes of HapticNet (hard, medium, soft, hard-skin), in
// the order of its outputs. Defined once here: the simulated world's food
// categories, the haptic pipeline and the clients all use this enum.
#ifndef BITEWISE_SERVICES_DOMAIN_HAPTIC_CLASS_H_
#define BITEWISE_SERVICES_DOMAIN_HAPTIC_CLASS_H_

namespace bitewise::domain {

enum class HapticClass { kHard = 0, kMedium = 1, kSoft = 2, kHardSkin = 3 };
inline constexpr int kHapticClasses = 4;

// Identifier form, as in label files: "hard", "medium", "soft", "hard_skin".
inline const char* HapticClassName(HapticClass haptic_class) {
  switch (haptic_class) {
    case HapticClass::kHard:
      return "hard";
    case HapticClass::kMedium:
      return "medium";
    case HapticClass::kSoft:
      return "soft";
    case HapticClass::kHardSkin:
      return "hard_skin";
  }
  return "unknown";
}

// For people: "hard", "medium", "soft", "hard-skin".
inline const char* HapticClassLabel(HapticClass haptic_class) {
  return haptic_class == HapticClass::kHardSkin ? "hard-skin"
                                                : HapticClassName(haptic_class);
}

}  // namespace bitewise::domain

#endif  // BITEWISE_SERVICES_DOMAIN_HAPTIC_CLASS_H_
