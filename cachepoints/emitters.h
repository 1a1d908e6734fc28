// The units a many-lights sampler chooses among, and the unoccluded estimate
// of what one of them delivers to a point.
//
// Every light is one emitter, except that an area light on a triangle mesh is
// one emitter per triangle (pbrt-v4's semantics: a mesh light of 100k
// triangles is sampled as well as 100k separate lights).  The estimate is
// conservative in angle: an emitter of angular radius alpha counts as facing
// a receiver if any of its directions could, so an emitter that lights a
// point never gets a zero estimate from the cosines alone.
#pragma once

#include "core/math.h"
#include "scene/lights.h"

#include <array>
#include <vector>

namespace theia {

enum class EmitterKind : uint8_t {
  Area,      // a triangle, or a whole non-mesh area light (sphere, disk, cylinder)
  PointLike, // point, spot, goniometric, projection: intensity from light_intensity()
  Infinite,  // environment or constant sky: always far
  Distant,   // always far
};

struct Emitter {
  int light = -1;
  int primitive = -1;       // the triangle of a mesh light, else -1
  EmitterKind kind = EmitterKind::Area;
  bool two_sided = false;
  vec3 center{0.0f};
  vec3 normal{0.0f};        // Area: the emitting side's unit normal; zero for a non-planar shape
  float radius = 0.0f;      // bounding radius about center
  float area = 0.0f;
  float radiance = 0.0f;    // luminance: mean radiance (Area, Infinite), radiance (Distant)
  vec3 direction{0.0f};     // Distant: unit, towards the light
};

struct EmitterSet {
  std::vector<Emitter> emitters;
  std::vector<int> first;  // per light: its first emitter (a mesh light's are consecutive)
  std::vector<int> count;  // per light: its emitters

  // The emitter of (light, primitive); primitive is ignored for a light of one
  // emitter.  -1 when out of range.
  int find(int light, int primitive) const {
    if (light < 0 || size_t(light) >= first.size()) return -1;
    if (count[size_t(light)] == 1) return first[size_t(light)];
    if (primitive < 0 || primitive >= count[size_t(light)]) return -1;
    return first[size_t(light)] + primitive;
  }
  size_t size() const { return emitters.size(); }
};

EmitterSet build_emitters(const LightSet& lights);
// build_emitters(lights).size(), without building them.
size_t emitter_count(const LightSet& lights);

// Seven sensors at a point: irradiance on planes facing +x, -x, +y, -y, +z,
// -z, and the fluence at the point (the omnidirectional bin).
inline constexpr int kSensorBins = 7;
inline constexpr int kFluenceBin = 6;
using SensorValues = std::array<float, kSensorBins>;

// Unoccluded estimates at p (luminance): on a surface with unit normal n
// (either side: a geometric normal's orientation is the mesh's winding), or
// the fluence where n is zero (media, hair).
float emitter_importance(const LightSet& lights, const Emitter& e, const vec3& p, const vec3& n);
SensorValues emitter_sensors(const LightSet& lights, const Emitter& e, const vec3& p);

}  // namespace theia
