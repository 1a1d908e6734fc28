#include "core/log.h"

#include <cstdio>
#include <mutex>

namespace theia {

namespace {
std::atomic<int> g_verbosity{static_cast<int>(Verbosity::Normal)};
std::atomic<int> g_warnings{0};
std::mutex g_print_mutex;
}  // namespace

void set_verbosity(Verbosity v) { g_verbosity = static_cast<int>(v); }
Verbosity verbosity() { return static_cast<Verbosity>(g_verbosity.load()); }
int warning_count() { return g_warnings.load(); }

void log_info_str(const std::string& msg) {
  if (verbosity() == Verbosity::Quiet) return;
  std::lock_guard lock(g_print_mutex);
  std::fprintf(stderr, "%s\n", msg.c_str());
}

void log_warning_str(const std::string& msg) {
  ++g_warnings;
  std::lock_guard lock(g_print_mutex);
  std::fprintf(stderr, "warning: %s\n", msg.c_str());
}

std::string error_line(const std::string& message) {
  const size_t at = message.find(": error: ");
  // A location has no spaces before its ": error: " (paths with spaces aside).
  if (at != std::string::npos && at > 0 && message.find(' ') > at) return message;
  return "error: " + message;
}

}  // namespace theia
