#include "scene/noise.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace theia {

namespace {

// Ken Perlin's permutation of 0..255, the table pbrt-v4 uses.  pbrt-v4 stores
// it twice over so that sums of two entries index it directly; `perm` wraps
// instead, which reads the same values.
constexpr uint8_t kPerm[256] = {
    151, 160, 137, 91,  90,  15,  131, 13,  201, 95,  96,  53,  194, 233, 7,   225, 140, 36,  103, 30,  69,  142,
    8,   99,  37,  240, 21,  10,  23,  190, 6,   148, 247, 120, 234, 75,  0,   26,  197, 62,  94,  252, 219, 203,
    117, 35,  11,  32,  57,  177, 33,  88,  237, 149, 56,  87,  174, 20,  125, 136, 171, 168, 68,  175, 74,  165,
    71,  134, 139, 48,  27,  166, 77,  146, 158, 231, 83,  111, 229, 122, 60,  211, 133, 230, 220, 105, 92,  41,
    55,  46,  245, 40,  244, 102, 143, 54,  65,  25,  63,  161, 1,   216, 80,  73,  209, 76,  132, 187, 208, 89,
    18,  169, 200, 196, 135, 130, 116, 188, 159, 86,  164, 100, 109, 198, 173, 186, 3,   64,  52,  217, 226, 250,
    124, 123, 5,   202, 38,  147, 118, 126, 255, 82,  85,  212, 207, 206, 59,  227, 47,  16,  58,  17,  182, 189,
    28,  42,  223, 183, 170, 213, 119, 248, 152, 2,   44,  154, 163, 70,  221, 153, 101, 155, 167, 43,  172, 9,
    129, 22,  39,  253, 19,  98,  108, 110, 79,  113, 224, 232, 178, 185, 112, 104, 218, 246, 97,  228, 251, 34,
    242, 193, 238, 210, 144, 12,  191, 179, 162, 241, 81,  51,  145, 235, 249, 14,  239, 107, 49,  192, 214, 31,
    181, 199, 106, 157, 184, 84,  204, 176, 115, 121, 50,  45,  127, 4,   150, 254, 138, 236, 205, 93,  222, 114,
    67,  29,  24,  72,  243, 141, 128, 195, 78,  66,  215, 61,  156, 180};

inline int perm(int i) { return kPerm[i & 255]; }

// The dot product of the lattice point's pseudo-random gradient (one of 12
// edge directions of a cube, 4 of them repeated) with the offset from it.
inline float gradient(int x, int y, int z, float dx, float dy, float dz) {
  int h = perm(perm(perm(x) + y) + z) & 15;
  float u = h < 8 || h == 12 || h == 13 ? dx : dy;
  float v = h < 4 || h == 12 || h == 13 ? dy : dz;
  return ((h & 1) ? -u : u) + ((h & 2) ? -v : v);
}

// 6t^5 - 15t^4 + 10t^3: zero first and second derivatives at 0 and 1, so the
// noise is C2 across cell faces.
inline float fade(float t) {
  float t3 = t * t * t, t4 = t3 * t;
  return 6.0f * t4 * t - 15.0f * t4 + 10.0f * t3;
}

inline float lerp(float t, float a, float b) { return (1.0f - t) * a + t * b; }

inline float smooth_step(float x, float a, float b) {
  float t = std::clamp((x - a) / (b - a), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

}  // namespace

float perlin_noise(float x, float y, float z) {
  // Coordinates past 2^30 would overflow the int cell index; pbrt-v4 wraps them.
  const float wrap = float(1 << 30);
  x = std::fmod(x, wrap);
  y = std::fmod(y, wrap);
  z = std::fmod(z, wrap);
  if (!std::isfinite(x + y + z)) return 0.0f;  // fmod of an infinity is NaN
  float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  int ix = int(fx) & 255, iy = int(fy) & 255, iz = int(fz) & 255;
  float dx = x - fx, dy = y - fy, dz = z - fz;

  float w000 = gradient(ix, iy, iz, dx, dy, dz);
  float w100 = gradient(ix + 1, iy, iz, dx - 1, dy, dz);
  float w010 = gradient(ix, iy + 1, iz, dx, dy - 1, dz);
  float w110 = gradient(ix + 1, iy + 1, iz, dx - 1, dy - 1, dz);
  float w001 = gradient(ix, iy, iz + 1, dx, dy, dz - 1);
  float w101 = gradient(ix + 1, iy, iz + 1, dx - 1, dy, dz - 1);
  float w011 = gradient(ix, iy + 1, iz + 1, dx, dy - 1, dz - 1);
  float w111 = gradient(ix + 1, iy + 1, iz + 1, dx - 1, dy - 1, dz - 1);

  float wx = fade(dx), wy = fade(dy), wz = fade(dz);
  float y0 = lerp(wy, lerp(wx, w000, w100), lerp(wx, w010, w110));
  float y1 = lerp(wy, lerp(wx, w001, w101), lerp(wx, w011, w111));
  return lerp(wz, y0, y1);
}

float noise_octaves(vec3 dpdx, vec3 dpdy, int max_octaves) {
  float len2 = std::max(glm::dot(dpdx, dpdx), glm::dot(dpdy, dpdy));
  // Octave i has period ~2^-i: keep those longer than twice the footprint.
  float n = -1.0f - std::log2(len2) / 2.0f;
  if (std::isnan(n)) n = float(max_octaves);  // an infinite or NaN footprint: as none
  return std::clamp(n, 0.0f, float(std::max(max_octaves, 0)));
}

float fbm(vec3 p, vec3 dpdx, vec3 dpdy, float omega, int max_octaves) {
  float n = noise_octaves(dpdx, dpdy, max_octaves);
  int whole = int(std::floor(n));
  float sum = 0.0f, lambda = 1.0f, o = 1.0f;
  for (int i = 0; i < whole; ++i) {
    sum += o * perlin_noise(lambda * p);
    lambda *= 1.99f;  // not 2: octaves would line up their lattice zeros
    o *= omega;
  }
  return sum + o * smooth_step(n - float(whole), 0.3f, 0.7f) * perlin_noise(lambda * p);
}

float turbulence(vec3 p, vec3 dpdx, vec3 dpdy, float omega, int max_octaves) {
  float n = noise_octaves(dpdx, dpdy, max_octaves);
  int whole = int(std::floor(n));
  float sum = 0.0f, lambda = 1.0f, o = 1.0f;
  for (int i = 0; i < whole; ++i) {
    sum += o * std::abs(perlin_noise(lambda * p));
    lambda *= 1.99f;
    o *= omega;
  }
  // The partial octave fades from the mean of |noise| (0.2) to its value; the
  // dropped octaves add their mean.  As pbrt-v4, the partial octave and the
  // first dropped one share the weight o.
  sum += o * lerp(smooth_step(n - float(whole), 0.3f, 0.7f), 0.2f, std::abs(perlin_noise(lambda * p)));
  for (int i = whole; i < max_octaves; ++i) {
    sum += o * 0.2f;
    o *= omega;
  }
  return sum;
}

}  // namespace theia
