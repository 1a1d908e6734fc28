#include "scheduler/schedule.h"

#include "core/log.h"
#include "core/stats.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace theia {

std::vector<int> make_schedule(const ScheduleOptions& o, int total_spp) {
  if (total_spp <= 0) throw_error("the schedule needs a positive total spp, got {}", total_spp);
  // The fields are the command line's --iteration-NAME overrides (schedule.h), so the messages name those.
  if (o.first <= 0) throw_error("--iteration-first (the first iteration size) must be positive, got {}", o.first);
  if (o.max < o.first)
    throw_error("--iteration-max ({}) is below the first iteration size, --iteration-first ({})", o.max, o.first);
  if (o.repeat < 1) throw_error("--iteration-repeat (uses of the first size) must be at least 1, got {}", o.repeat);
  if (!(o.growth >= 1.0) || !std::isfinite(o.growth))
    throw_error("--iteration-growth (the growth factor of iteration sizes) must be at least 1, got {}", o.growth);
  std::vector<int> sizes;
  int done = 0;
  double size = o.first;
  while (done < total_spp) {
    int n = int(std::min<double>(std::floor(size), o.max));
    n = std::min(n, total_spp - done);
    sizes.push_back(n);
    done += n;
    if (int(sizes.size()) >= o.repeat) size = std::min<double>(size * o.growth, o.max);
  }
  return sizes;
}

std::vector<int> clip_schedule(const std::vector<int>& sizes, int begin, int end) {
  std::vector<int> clipped;
  int at = 0;
  for (int n : sizes) {
    const int lo = std::max(at, begin), hi = std::min(at + n, end);
    if (hi > lo) clipped.push_back(hi - lo);
    at += n;
  }
  return clipped;
}

std::vector<int> fit_iteration(const std::vector<int>& sizes, int at, double seconds_left, double seconds_per_spp) {
  if (at < 0 || at >= int(sizes.size()) || !(seconds_per_spp > 0.0)) return sizes;
  const int planned = sizes[size_t(at)];
  const int fits = int(std::clamp(std::floor(seconds_left / seconds_per_spp), 1.0, double(planned)));
  if (fits >= planned) return sizes;
  std::vector<int> cut = sizes;
  cut[size_t(at)] = fits;
  cut.insert(cut.begin() + at + 1, planned - fits);
  return cut;
}

std::vector<int> switch_schedule(const std::vector<int>& sizes, int at, const ScheduleOptions& options) {
  if (at < 0 || at >= int(sizes.size())) return sizes;
  int done = 0, total = 0;
  for (size_t i = 0; i < sizes.size(); ++i) (int(i) < at ? done : total) += sizes[i];
  total += done;
  std::vector<int> rest = clip_schedule(make_schedule(options, total), done, total);
  if (rest.size() > 1 && rest[0] < options.first) {
    rest[1] += rest[0];
    rest.erase(rest.begin());
  }
  std::vector<int> switched(sizes.begin(), sizes.begin() + at);
  switched.insert(switched.end(), rest.begin(), rest.end());
  return switched;
}

std::vector<int> cumulative_spp(const std::vector<int>& sizes) {
  std::vector<int> c(sizes.size());
  int sum = 0;
  for (size_t i = 0; i < sizes.size(); ++i) c[i] = sum += sizes[i];
  return c;
}

std::vector<bool> checkpoint_iterations(const std::vector<int>& cumulative, int first_ideal, bool every_iteration) {
  std::vector<bool> write(cumulative.size(), every_iteration);
  if (every_iteration || cumulative.empty()) return write;
  const int total = cumulative.back();
  std::vector<int> ideals;
  for (int64_t ideal = std::max(first_ideal, 1); ideal < total; ideal *= 2) ideals.push_back(int(ideal));
  ideals.push_back(total);
  for (int ideal : ideals) {
    // The last iteration whose running total does not pass the ideal count.
    auto it = std::upper_bound(cumulative.begin(), cumulative.end(), ideal);
    if (it != cumulative.begin()) write[size_t(it - cumulative.begin()) - 1] = true;
  }
  return write;
}

void IterationTasks::add(BetweenIterationSlot slot, Task task) { slots_[size_t(slot)].push_back(std::move(task)); }

void IterationTasks::begin_iteration(const IterationInfo& it) const {
  for (const Task& h : begin_hooks_) h(it);
}

void IterationTasks::end_iteration(const IterationInfo& it) {
  {
    ScopedTimer timer(end_hook_seconds_);
    for (const Task& h : end_hooks_) h(it);
  }
  for (size_t s = 0; s < size_t(BetweenIterationSlot::Count); ++s) {
    if (slots_[s].empty()) continue;
    ScopedTimer timer(seconds_[s]);
    for (const Task& t : slots_[s]) t(it);
  }
}

}  // namespace theia
