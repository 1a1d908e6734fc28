// A bounded, thread-safe cache of a pure function's results, for load-time
// work a scene repeats with the same arguments (the same conductor colour,
// metal or blackbody range in many materials and media).  A hit returns
// exactly what the computation returned; when full it starts over.
#pragma once

#include <cstddef>
#include <map>
#include <mutex>
#include <utility>

namespace theia {

template <typename Key, typename Value>
class BoundedMemo {
 public:
  explicit BoundedMemo(size_t capacity) : capacity_(capacity) {}

  // compute() runs outside the lock: two threads may both compute a new key.
  template <typename Compute>
  Value get(const Key& key, Compute&& compute) {
    {
      std::lock_guard lock(mutex_);
      if (auto it = values_.find(key); it != values_.end()) return it->second;
    }
    Value v = compute();
    std::lock_guard lock(mutex_);
    if (values_.size() >= capacity_) values_.clear();
    values_.emplace(key, v);
    return v;
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::map<Key, Value> values_;
};

}  // namespace theia
