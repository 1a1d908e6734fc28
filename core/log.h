// Messages to the user.  Warnings go to stderr and are counted (the JSON log
// reports the count); errors are exceptions carrying one complete message,
// caught once in app/ which prints it and exits non-zero.
#pragma once

#include <fmt/core.h>

#include <atomic>
#include <stdexcept>
#include <string>

namespace theia {

// Raised for bad input: a malformed scene, a missing file, an impossible option.
// The message is complete ("file:line:column: what was expected").
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The one line a user sees for an error: "WHERE: error: WHAT" when the
// message names where it was found (file:line:column, a file), else
// "error: WHAT" -- never "error: f.pbrt:3:1: error: ...".
std::string error_line(const std::string& message);

enum class Verbosity { Quiet, Normal, Verbose };

void set_verbosity(Verbosity v);
Verbosity verbosity();
int warning_count();

void log_info_str(const std::string& msg);
void log_warning_str(const std::string& msg);

template <typename... Args>
void log_info(fmt::format_string<Args...> f, Args&&... args) {
  log_info_str(fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void log_warning(fmt::format_string<Args...> f, Args&&... args) {
  log_warning_str(fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
[[noreturn]] void throw_error(fmt::format_string<Args...> f, Args&&... args) {
  throw Error(fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace theia
