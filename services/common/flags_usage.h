// Makes `--help` list each binary's own flags. Abseil's default shows only
// flags defined in a file named like the program, and every bitewise main
// is main.cc, so `--help` said "No flags matched". Call before
// absl::ParseCommandLine; --helpfull still lists Abseil's own flags too.
#ifndef BITEWISE_SERVICES_COMMON_FLAGS_USAGE_H_
#define BITEWISE_SERVICES_COMMON_FLAGS_USAGE_H_

#include "absl/flags/usage_config.h"
#include "absl/strings/match.h"
#include "absl/strings/string_view.h"

namespace bitewise {

inline void ShowOwnFlagsInHelp() {
  absl::FlagsUsageConfig config;
  config.contains_help_flags = [](absl::string_view file) {
    return !absl::StrContains(file, "absl/");
  };
  config.contains_helpshort_flags = config.contains_help_flags;
  absl::SetFlagsUsageConfig(config);
}

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_FLAGS_USAGE_H_
