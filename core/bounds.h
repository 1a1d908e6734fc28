// Axis-aligned boxes.  An empty box has min > max so that union with it is a no-op.
#pragma once

#include "core/math.h"

namespace theia {

struct Bounds3 {
  vec3 min{kInfinity};
  vec3 max{-kInfinity};

  Bounds3() = default;
  explicit Bounds3(const vec3& p) : min(p), max(p) {}
  Bounds3(const vec3& a, const vec3& b) : min(glm::min(a, b)), max(glm::max(a, b)) {}

  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  vec3 diagonal() const { return empty() ? vec3(0.0f) : max - min; }
  vec3 centroid() const { return 0.5f * (min + max); }
  bool contains(const vec3& p) const {
    return p.x >= min.x && p.x <= max.x && p.y >= min.y && p.y <= max.y && p.z >= min.z && p.z <= max.z;
  }
  // Position of p relative to the box: (0,0,0) at min, (1,1,1) at max.  Flat
  // axes map to 0 instead of dividing by zero.
  vec3 offset(const vec3& p) const {
    vec3 o = p - min;
    vec3 d = max - min;
    for (int i = 0; i < 3; ++i)
      if (d[i] > 0.0f) o[i] /= d[i];
      else o[i] = 0.0f;
    return o;
  }
};

inline Bounds3 union_bounds(const Bounds3& b, const vec3& p) {
  Bounds3 r;
  r.min = glm::min(b.min, p);
  r.max = glm::max(b.max, p);
  return r;
}
inline Bounds3 union_bounds(const Bounds3& a, const Bounds3& b) {
  Bounds3 r;
  r.min = glm::min(a.min, b.min);
  r.max = glm::max(a.max, b.max);
  return r;
}

}  // namespace theia
