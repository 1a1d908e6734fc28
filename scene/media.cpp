#include "scene/media.h"

#include "core/color.h"
#include "core/memo.h"
#include "scene/noise.h"
#include "scene/shape_bounds.h"
#include "scene/spectrum.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>

namespace theia {

namespace {

template <class T>
T voxel(const Medium& m, const std::vector<T>& values, int x, int y, int z) {
  if (x < 0 || y < 0 || z < 0 || x >= m.nx || y >= m.ny || z >= m.nz) return T(0.0f);
  return values[(size_t(z) * size_t(m.ny) + size_t(y)) * size_t(m.nx) + size_t(x)];
}
float voxel(const Medium& m, int x, int y, int z) { return voxel(m, m.density, x, y, z); }

// pbrt-v4's SampledGrid::Lookup: trilinear between voxel centres over the
// box p0-p1, zero outside.
template <class T>
T trilinear(const Medium& m, const std::vector<T>& v, const vec3& p) {
  const vec3 u = (p - m.p0) / (m.p1 - m.p0);
  const vec3 g(u.x * float(m.nx) - 0.5f, u.y * float(m.ny) - 0.5f, u.z * float(m.nz) - 0.5f);
  const vec3 f = glm::floor(g);
  const int x = int(f.x), y = int(f.y), z = int(f.z);
  const vec3 d = g - f;
  // The 8 corners (c[dz][dy][dx]): inside the grid read straight from their
  // first corner, at the border one by one (zero outside).  One lerp code for
  // both, so that both round alike.
  T c[2][2][2];
  if (x >= 0 && y >= 0 && z >= 0 && x + 1 < m.nx && y + 1 < m.ny && z + 1 < m.nz) {
    const size_t sy = size_t(m.nx), sz = size_t(m.nx) * size_t(m.ny);
    const T* b = &v[size_t(z) * sz + size_t(y) * sy + size_t(x)];
    c[0][0][0] = b[0], c[0][0][1] = b[1], c[0][1][0] = b[sy], c[0][1][1] = b[sy + 1];
    c[1][0][0] = b[sz], c[1][0][1] = b[sz + 1], c[1][1][0] = b[sz + sy], c[1][1][1] = b[sz + sy + 1];
  } else {
    for (int k = 0; k < 2; ++k)
      for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) c[k][j][i] = voxel(m, v, x + i, y + j, z + k);
  }
  auto lerp = [](float t, const T& a, const T& b) { return (1.0f - t) * a + t * b; };
  const T d00 = lerp(d.x, c[0][0][0], c[0][0][1]);
  const T d10 = lerp(d.x, c[0][1][0], c[0][1][1]);
  const T d01 = lerp(d.x, c[1][0][0], c[1][0][1]);
  const T d11 = lerp(d.x, c[1][1][0], c[1][1][1]);
  return lerp(d.z, lerp(d.y, d00, d10), lerp(d.y, d01, d11));
}

// The factor that turns a majorant-grid cell into sigma_maj: the rgbgrid's
// cells hold sigma_t bounds already, the others density bounds.
float majorant_scale(const Medium& m) {
  return m.kind == MediumKind::RGBGrid ? 1.0f : max_component(m.sigma_a + m.sigma_s);
}

// The optical depth to the next tentative collision, -log(1 - u): divided by
// the majorant it is the distance.  log(1 - u), not log1p(-u): u is a
// multiple of 2^-24 (to_unit_float, and the sampler's to_sample), so 1 - u is
// exact and the two differ by rounding only, while glibc's logf takes about
// half the instructions of its log1pf, which was a tenth of a smoke-grid render.
float exponential_depth(float u) { return -std::log(1.0f - u); }

// Majorant cells per axis: kMajorantGridRes (pbrt-v4's 16), but no finer
// than kVoxelsPerMajorantCell voxels of the grid's longest axis a cell.  A
// ray crosses every cell on its way, collision or not, and a shadow ray
// through smoke-grid's 32^3 grid crossed ~11 cells for ~1 collision: 8^3
// cells there cost 2.5% fewer instructions a render, 4^3 0.3% (their looser
// bounds' null collisions eat the rest).  A cloud's bound follows only its
// altitude: it keeps kMajorantGridRes.
constexpr int kVoxelsPerMajorantCell = 4;
int majorant_res(const Medium& m) {
  if (m.kind == MediumKind::Cloud) return kMajorantGridRes;
  const int n = std::max({m.nx, m.ny, m.nz});
  return std::clamp((n + kVoxelsPerMajorantCell - 1) / kVoxelsPerMajorantCell, 1, kMajorantGridRes);
}

// Optical depth not drawn yet (kNoDepth) or left over from the spans walked so far.
constexpr float kNoDepth = -1.0f;

// Collisions at rate sigma_maj in [s, s_end]; false when visit stopped.
// Past s_end the walk goes on at s_end with the optical depth it has not used
// (`depth`): the next span's collision is where the leftover runs out at its
// own rate.  That is the same Poisson process as a fresh exponential per span
// (which is memoryless), but a ray that crosses many majorant cells draws one
// number per collision instead of one per cell (smoke-grid crossed ~14 cells
// per collision, each with its logf and hash).  Within one span (a
// homogeneous medium) the distances are those of a fresh draw per collision.
// Inlined: a grid's walk calls it once per majorant cell, most of which it
// only crosses.
template <class Visit>
[[gnu::always_inline]] inline bool walk_span(const Medium& m, const MediumSegment& seg, double& s, double s_end,
                                             float sigma_maj, float& depth, TrackingRng& rng, Visit& visit) {
  if (!(sigma_maj > 0.0f)) {
    s = s_end;
    return true;
  }
  while (true) {
    if (depth == kNoDepth) depth = exponential_depth(rng.next());
    const double s_next = s + double(depth / sigma_maj);
    if (!(s_next < s_end)) {
      depth = std::max(depth - float((s_end - s) * double(sigma_maj)), 0.0f);
      s = s_end;
      return true;
    }
    s = s_next;
    depth = kNoDepth;
    const vec3 p = seg.o + seg.d * float(s);
    if (!visit(medium_props(m, p), sigma_maj, float(s * double(seg.t_per_s)))) return false;
  }
}

// walk_span out of line, for a medium walked as one span (homogeneous, or a
// grid without majorants): compiled as before the grid's walk inlined
// walk_span, so that homogeneous media's images stay bit for bit.
template <class Visit>
[[gnu::noinline]] bool walk_one_span(const Medium& m, const MediumSegment& seg, double& s, double s_end,
                                     float sigma_maj, float& depth, TrackingRng& rng, Visit& visit) {
  return walk_span(m, seg, s, s_end, sigma_maj, depth, rng, visit);
}

// A grid's walk, cell by cell of its majorant grid (a 3D DDA), so that the
// collision rate follows the local density bound.
template <class Visit>
bool walk_grid(const Medium& m, const MediumSegment& seg, TrackingRng& rng, Visit& visit) {
  const int res = majorant_res(m);
  const vec3 cells_per_unit = float(res) / (m.p1 - m.p0);
  const vec3 g0 = (seg.o + seg.d * seg.s0 - m.p0) * cells_per_unit;
  int cell[3], step[3];
  double next[3], delta[3];
  for (int a = 0; a < 3; ++a) {
    cell[a] = std::clamp(int(std::floor(g0[a])), 0, res - 1);
    const double rate = double(seg.d[a]) * double(cells_per_unit[a]);  // cells per unit distance
    if (rate == 0.0) {
      step[a] = 0, next[a] = kInfinity, delta[a] = kInfinity;
    } else {
      step[a] = rate > 0.0 ? 1 : -1;
      const double boundary = rate > 0.0 ? cell[a] + 1 : cell[a];
      next[a] = double(seg.s0) + (boundary - double(g0[a])) / rate;
      delta[a] = 1.0 / std::abs(rate);
    }
  }
  const float sigma_t_max = majorant_scale(m);
  // The stepping state in scalars, not in arrays indexed by the axis that
  // steps: those went through the stack, a store and a reload on the loop's
  // critical path per cell crossed (most of a walk's cells see no
  // collision).  The same numbers in the same order: the walk is unchanged.
  double n0 = next[0], n1 = next[1], n2 = next[2];
  int c0 = cell[0], c1 = cell[1], c2 = cell[2];
  const ptrdiff_t stride1 = res, stride2 = ptrdiff_t(res) * res;
  ptrdiff_t index = (ptrdiff_t(c2) * res + c1) * res + c0;
  const float* majorants = m.majorants.data();
  const double s1 = double(seg.s1);
  double s = seg.s0;
  float depth = kNoDepth;
  while (true) {
    const int a = n0 < n1 ? (n0 < n2 ? 0 : 2) : (n1 < n2 ? 1 : 2);
    const double s_end = std::min(s1, a == 0 ? n0 : (a == 1 ? n1 : n2));
    if (!walk_span(m, seg, s, s_end, sigma_t_max * majorants[index], depth, rng, visit)) return false;
    if (s_end >= s1) return true;
    if (a == 0) {
      c0 += step[0];
      if (c0 < 0 || c0 >= res) return true;
      n0 += delta[0];
      index += step[0];
    } else if (a == 1) {
      c1 += step[1];
      if (c1 < 0 || c1 >= res) return true;
      n1 += delta[1];
      index += step[1] * stride1;
    } else {
      c2 += step[2];
      if (c2 < 0 || c2 >= res) return true;
      n2 += delta[2];
      index += step[2] * stride2;
    }
  }
}

// Walks the tentative collisions of `m` along `ray` in [0, tmax]: visit(point
// props, sigma_maj, t) returns false to stop.  Returns true if the walk left
// the segment (no stop).  The walk's position is in double: thousands of
// steps in a dense medium would otherwise round the sum.
template <class Visit>
bool walk_collisions(const Medium& m, const Ray& ray, float tmax, TrackingRng& rng, Visit&& visit) {
  const MediumSegment seg = medium_segment(m, ray, 0.0f, tmax);
  if (seg.empty()) return true;
  if (m.kind != MediumKind::Homogeneous && !m.majorants.empty()) return walk_grid(m, seg, rng, visit);
  double s = seg.s0;
  float depth = kNoDepth;
  return walk_one_span(m, seg, s, double(seg.s1), medium_majorant(m), depth, rng, visit);
}

float average(const RGB& c) { return (c.x + c.y + c.z) * (1.0f / 3.0f); }

}  // namespace

float cloud_density(const Medium& m, const vec3& p) {
  vec3 pp = m.frequency * p;
  if (m.wispiness > 0.0f) {
    // Domain warping by the noise's gradient: the wisps.
    float vomega = 0.05f * m.wispiness, vlambda = 10.0f;
    for (int i = 0; i < 2; ++i) {
      pp += vomega * perlin_noise_gradient(vlambda * pp);
      vomega *= 0.5f;
      vlambda *= 1.99f;
    }
  }
  float d = 0.0f, omega = 0.5f, lambda = 1.0f;
  for (int i = 0; i < kCloudOctaves; ++i) {
    d += omega * perlin_noise(lambda * pp);
    omega *= 0.5f;
    lambda *= 1.99f;
  }
  // Thinning with altitude, and a solid base below y = 0.5.
  d = std::clamp((1.0f - p.y) * 4.5f * m.cloud_density * d, 0.0f, 1.0f);
  d += 2.0f * std::max(0.0f, 0.5f - p.y);
  return std::clamp(d, 0.0f, 1.0f);
}

bool medium_is_emissive(const Medium& m) {
  return !is_black(m.Le) || (!m.Le_grid.empty() && m.Le_scale > 0.0f) || !m.blackbody_table.empty();
}

float medium_density(const Medium& m, const vec3& p) {
  switch (m.kind) {
    case MediumKind::Homogeneous:
    case MediumKind::RGBGrid: return 1.0f;
    case MediumKind::Cloud: return cloud_density(m, p);
    case MediumKind::UniformGrid:
    case MediumKind::NanoVDB: break;
  }
  return trilinear(m, m.density, p);
}

// pbrt-v4 scales a grid's Le by "Lescale" looked up in a 1 x 1 x 1 grid,
// trilinearly like the density: 1 at the box's centre, falling linearly to
// 1/2 at each face (a product over the axes).
float grid_emission_scale(const Medium& m, const vec3& p) {
  const vec3 u = (p - m.p0) / (m.p1 - m.p0);
  const vec3 f = glm::max(vec3(1.0f) - glm::abs(u - vec3(0.5f)), vec3(0.0f));
  return f.x * f.y * f.z;
}

RGB blackbody_emission(const Medium& m, float kelvin) {
  const float t = (kelvin - m.temperature_offset) * m.temperature_scale;
  if (!(t > kMinEmittingKelvin) || m.blackbody_table.empty()) return RGB(0.0f);
  const float x = std::min((t - kMinEmittingKelvin) / (m.blackbody_t_max - kMinEmittingKelvin), 1.0f) *
                  float(m.blackbody_table.size() - 1);
  const size_t i = std::min(size_t(x), m.blackbody_table.size() - 2);
  const float f = x - float(i);
  return (1.0f - f) * m.blackbody_table[i] + f * m.blackbody_table[i + 1];
}

namespace {

// Le of a uniformgrid or nanovdb: "Le" or the temperature's blackbody, times
// "Lescale" (a uniformgrid's as a grid, pbrt-v4's 1 x 1 x 1 one by default).
RGB grid_emission(const Medium& m, const vec3& p) {
  const bool hot = !m.temperature.empty();
  if (!hot && is_black(m.Le)) return RGB(0.0f);
  float scale = m.Le_scale;
  if (m.kind == MediumKind::UniformGrid)
    scale = m.Le_scale_grid.empty() ? grid_emission_scale(m, p) : trilinear(m, m.Le_scale_grid, p);
  if (!hot) return m.Le * scale;
  if (m.kind == MediumKind::UniformGrid && m.Le_scale_grid.empty()) scale *= m.Le_scale;
  return blackbody_emission(m, trilinear(m, m.temperature, p)) * scale;
}

MediumProps rgb_grid_props(const Medium& m, const vec3& p) {
  MediumProps mp;
  mp.sigma_a = m.sigma_a * (m.sigma_a_grid.empty() ? RGB(1.0f) : trilinear(m, m.sigma_a_grid, p));
  mp.sigma_s = m.sigma_s * (m.sigma_s_grid.empty() ? RGB(1.0f) : trilinear(m, m.sigma_s_grid, p));
  if (!m.Le_grid.empty()) mp.Le = m.Le_scale * trilinear(m, m.Le_grid, p);
  return mp;
}

}  // namespace

MediumProps medium_props(const Medium& m, const vec3& p) {
  switch (m.kind) {
    case MediumKind::Homogeneous: return MediumProps{m.sigma_a, m.sigma_s, m.Le};
    case MediumKind::RGBGrid: return rgb_grid_props(m, p);
    case MediumKind::Cloud: {
      const float d = cloud_density(m, p);
      return MediumProps{m.sigma_a * d, m.sigma_s * d, RGB(0.0f)};
    }
    case MediumKind::UniformGrid:
    case MediumKind::NanoVDB: break;
  }
  const float d = trilinear(m, m.density, p);
  return MediumProps{m.sigma_a * d, m.sigma_s * d, grid_emission(m, p)};
}

namespace {

// The largest of `values` over the voxels whose centres the trilinear lookup
// blends anywhere in majorant cell c.
template <class Bound>
float cell_max(const Medium& m, const int c[3], Bound&& bound) {
  const int res = majorant_res(m);
  const int n[3] = {m.nx, m.ny, m.nz};
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(int(std::floor(float(c[a]) / res * float(n[a]) - 0.5f)), 0);
    hi[a] = std::min(int(std::floor(float(c[a] + 1) / res * float(n[a]) - 0.5f)) + 1, n[a] - 1);
  }
  float v = 0.0f;
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i) v = std::max(v, bound(i, j, k));
  return v;
}

float rgb_cell_max(const Medium& m, const std::vector<RGB>& grid, const int c[3]) {
  if (grid.empty()) return 1.0f;
  return cell_max(m, c, [&](int i, int j, int k) { return max_component(voxel(m, grid, i, j, k)); });
}

// A bound on the cloud's density over the cell's altitudes [y0, y1]: its
// noise sum is at most kCloudNoiseSum in magnitude (every octave's |noise|
// <= 2: a convex blend of gradient dots of at most 2), so only the altitude
// falloff bounds it (cells above y = 1 with little falloff stay low).
float cloud_cell_bound(const Medium& m, float y0, float y1) {
  const float falloff = std::max(std::abs(1.0f - y0), std::abs(1.0f - y1));
  const float noise = std::min(falloff * 4.5f * std::abs(m.cloud_density) * kCloudNoiseSum, 1.0f);
  return std::min(noise + 2.0f * std::max(0.0f, 0.5f - y0), 1.0f);
}

float majorant_cell(const Medium& m, const int c[3]) {
  switch (m.kind) {
    case MediumKind::Homogeneous: return 1.0f;
    case MediumKind::RGBGrid: {
      // pbrt-v4's bound: the largest sigma_a plus the largest sigma_s.
      const float scale = max_component(m.sigma_a);
      return scale * (rgb_cell_max(m, m.sigma_a_grid, c) + rgb_cell_max(m, m.sigma_s_grid, c));
    }
    case MediumKind::Cloud: {
      const float h = (m.p1.y - m.p0.y) / float(majorant_res(m));
      return cloud_cell_bound(m, m.p0.y + float(c[1]) * h, m.p0.y + float(c[1] + 1) * h);
    }
    case MediumKind::UniformGrid:
    case MediumKind::NanoVDB: break;
  }
  return cell_max(m, c, [&](int i, int j, int k) { return voxel(m, i, j, k); });
}

}  // namespace

void build_majorant_grid(Medium& m) {
  const int res = majorant_res(m);
  m.majorants.assign(size_t(res) * res * res, 0.0f);
  for (int z = 0; z < res; ++z)
    for (int y = 0; y < res; ++y)
      for (int x = 0; x < res; ++x) {
        const int c[3] = {x, y, z};
        m.majorants[(size_t(z) * res + size_t(y)) * res + size_t(x)] = majorant_cell(m, c);
      }
  m.max_density = *std::max_element(m.majorants.begin(), m.majorants.end());
}

namespace {

// pbrt-v4's BlackbodySpectrum (Planck's law over its value at the peak
// wavelength, Wien's law) as RGB in the working space: its luminance
// (CIE Y over the integral of y-bar, 1 nm steps over 360-830 nm) times
// blackbody_rgb's colour of luminance 1.
RGB normalized_blackbody(float kelvin) {
  auto planck = [&](double lambda_nm) {
    const double c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23, l = lambda_nm * 1e-9;
    return (2.0 * h * c * c) / (std::pow(l, 5.0) * (std::exp((h * c) / (l * kb * double(kelvin))) - 1.0));
  };
  const double peak = planck(2.8977721e-3 / double(kelvin) * 1e9);
  double y = 0.0, y_bar = 0.0;
  for (int lambda = 360; lambda <= 830; ++lambda) {
    const double cmf_y = double(cie_xyz_cmf(float(lambda)).y);
    y += planck(double(lambda)) / peak * cmf_y;
    y_bar += cmf_y;
  }
  const RGB rgb = srgb_to_working(blackbody_rgb(kelvin)) * float(y / y_bar);
  const bool finite = std::isfinite(rgb.x) && std::isfinite(rgb.y) && std::isfinite(rgb.z);
  return finite ? rgb : RGB(0.0f);  // a cold body's Y underflows
}

}  // namespace

void build_blackbody_table(Medium& m) {
  m.blackbody_table.clear();
  if (m.temperature.empty()) return;
  // The hottest temperature a lookup can give: a voxel's, or 0 outside the grid.
  const auto [lo, hi] = std::minmax_element(m.temperature.begin(), m.temperature.end());
  float t_max = 0.0f;
  for (float t : {*lo, *hi, 0.0f}) t_max = std::max(t_max, (t - m.temperature_offset) * m.temperature_scale);
  if (!(t_max > kMinEmittingKelvin)) return;
  m.blackbody_t_max = t_max;
  // A quarter million Planck terms, the same for every medium of this hottest
  // temperature (kept by its bits).
  static BoundedMemo<uint32_t, std::vector<RGB>> tables(64);
  m.blackbody_table = tables.get(std::bit_cast<uint32_t>(t_max), [&] {
    std::vector<RGB> table(kBlackbodyTableSize);
    for (int i = 0; i < kBlackbodyTableSize; ++i)
      table[size_t(i)] = normalized_blackbody(kMinEmittingKelvin +
                                              (t_max - kMinEmittingKelvin) * float(i) / float(kBlackbodyTableSize - 1));
    return table;
  });
}

float medium_majorant(const Medium& m) { return majorant_scale(m) * m.max_density; }

MediumSegment medium_segment(const Medium& m, const Ray& ray, float t0, float t1) {
  MediumSegment seg;
  vec3 o = ray.o, d = ray.d;
  if (m.kind != MediumKind::Homogeneous) {
    // Transform::inverse() would copy both matrices (~175 instructions a
    // segment); this is its point() and vector() read in place.
    const mat4& inv = m.render_from_medium.m_inv;
    const vec4 r = inv * vec4(ray.o, 1.0f);
    o = r.w == 1.0f ? vec3(r) : vec3(r) / r.w;
    d = mat3(inv) * ray.d;
  }
  const float len = glm::length(d);
  if (!(len > 0.0f) || !std::isfinite(len)) return seg;
  seg.o = o;
  seg.d = d / len;
  seg.t_per_s = 1.0f / len;
  // Distances in double: an unbounded segment (a ray that leaves the scene) stays infinite.
  double s0 = double(t0) * len, s1 = double(t1) * len;
  if (m.kind != MediumKind::Homogeneous) {
    // The slab test against the grid's box: outside it the density is 0.
    for (int a = 0; a < 3; ++a) {
      const double inv = 1.0 / double(seg.d[a]);
      double near = (double(m.p0[a]) - double(o[a])) * inv, far = (double(m.p1[a]) - double(o[a])) * inv;
      if (near > far) std::swap(near, far);
      if (std::isnan(near) || std::isnan(far)) {  // parallel to the slab: inside it or not
        if (o[a] < m.p0[a] || o[a] > m.p1[a]) return MediumSegment{};
        continue;
      }
      s0 = std::max(s0, near);
      s1 = std::min(s1, far);
    }
  }
  seg.s0 = float(s0);
  seg.s1 = s1 > 3.0e38 ? kInfinity : float(s1);
  return seg;
}

namespace {

// A sphere that keeps a medium sealed (sealed_media): full, outward, opaque
// to shadow rays, not a light.
bool sealing_sphere(const Scene& scene, const Shape& s, const std::vector<uint8_t>& top_level) {
  const SphereParams& sp = s.sphere;
  const bool full = sp.radius > 0.0f && std::min(sp.zmin, sp.zmax) <= -sp.radius &&
                    std::max(sp.zmin, sp.zmax) >= sp.radius && sp.phimax >= 360.0f;
  if (s.kind != ShapeKind::Sphere || !full || s.reverse_orientation != s.transform_swaps_handedness) return false;
  const int index = int(&s - scene.shapes.data());
  if (!top_level[size_t(index)] || s.alpha >= 0 || s.area_light >= 0) return false;
  if (s.holdout || s.material < 0) return true;
  const MaterialKind k = scene.materials[size_t(s.material)].kind;
  return k != MaterialKind::Interface && k != MaterialKind::Mix;
}

// Render-space bounds of what a light emits from; empty for lights at
// infinity; nullopt where they are not known here.
std::optional<Bounds3> light_bounds(const Scene& scene, const Light& l, const std::vector<uint8_t>& top_level) {
  switch (l.kind) {
    case LightKind::Infinite:
    case LightKind::Distant: return Bounds3{};
    case LightKind::Point:
    case LightKind::Spot:
    case LightKind::Goniometric:
    case LightKind::Projection: return Bounds3(l.position);
    case LightKind::Area: break;
  }
  if (l.shape < 0 || !top_level[size_t(l.shape)]) return std::nullopt;
  return top_level_shape_bounds(scene, scene.shapes[size_t(l.shape)]);
}

// Whether box b (render space) lies outside sphere s by a margin.
bool outside_sphere(const Shape& s, const Bounds3& b) {
  if (b.empty()) return true;
  const Bounds3 o = transform_bounds(glm::dmat4(s.render_from_object.m_inv), b);
  const vec3 nearest = glm::clamp(vec3(0.0f), o.min, o.max);
  return glm::length(nearest) > 1.001f * s.sphere.radius;
}

}  // namespace

std::vector<uint8_t> sealed_media(const Scene& scene) {
  std::vector<uint8_t> top_level(scene.shapes.size(), 0);
  for (int i : scene.top_level_shapes) top_level[size_t(i)] = 1;
  std::vector<Bounds3> lights;
  for (const Light& l : scene.lights) {
    const std::optional<Bounds3> b = light_bounds(scene, l, top_level);
    if (!b) return std::vector<uint8_t>(scene.media.size(), 0);
    lights.push_back(*b);
  }
  std::vector<uint8_t> sealed(scene.media.size(), 1);
  if (scene.camera_medium >= 0) sealed[size_t(scene.camera_medium)] = 0;
  for (const Shape& s : scene.shapes) {
    if (!s.medium_transition()) continue;
    bool seals = s.medium_inside >= 0 && sealing_sphere(scene, s, top_level);
    for (const Bounds3& b : lights) seals = seals && outside_sphere(s, b);
    if (!seals) {
      for (int m : {s.medium_inside, s.medium_outside})
        if (m >= 0) sealed[size_t(m)] = 0;
    } else if (s.medium_outside >= 0) {
      sealed[size_t(s.medium_outside)] = 0;
    }
  }
  return sealed;
}

FreeFlight sample_free_flight(const Medium& m, const Ray& ray, float tmax, const RGB& beta_in, TrackingRng& rng) {
  FreeFlight ff;
  RGB beta = beta_in;
  const bool emissive = medium_is_emissive(m);
  walk_collisions(m, ray, tmax, rng, [&](const MediumProps& mp, float sigma_maj, float t) {
    if (emissive) ff.emitted += beta * mp.sigma_a * mp.Le / sigma_maj;
    const RGB sigma_n = glm::max(RGB(sigma_maj) - mp.sigma_a - mp.sigma_s, RGB(0.0f));
    // Event probabilities: throughput-weighted channel averages (they sum
    // to average(beta) * sigma_maj when nothing is clamped).
    const float pa = average(beta * mp.sigma_a), ps = average(beta * mp.sigma_s), pn = average(beta * sigma_n);
    const float c = pa + ps + pn;
    if (!(c > 0.0f)) {
      ff.event = MediumEvent::Absorb;
      return false;
    }
    const float u = rng.next() * c;
    ff.t = t;
    if (u < pa) {
      ff.event = MediumEvent::Absorb;
      return false;
    }
    if (u < pa + ps) {
      beta *= mp.sigma_s * (c / (sigma_maj * ps));
      ff.event = MediumEvent::Scatter;
      return false;
    }
    beta *= sigma_n * (c / (sigma_maj * pn));
    return true;
  });
  ff.beta = beta;
  return ff;
}

RGB ratio_tracking(const Medium& m, const Ray& ray, float tmax, TrackingRng& rng) {
  RGB T(1.0f);
  walk_collisions(m, ray, tmax, rng, [&](const MediumProps& mp, float sigma_maj, float) {
    T *= glm::max(RGB(1.0f) - (mp.sigma_a + mp.sigma_s) / sigma_maj, RGB(0.0f));
    const float q = max_component(T);
    if (!(q > 0.0f)) return false;
    if (q < 0.25f) {
      // Russian roulette: survive with probability q, weighted by 1/q.
      if (rng.next() >= q) {
        T = RGB(0.0f);
        return false;
      }
      T /= q;
    }
    return true;
  });
  return T;
}

}  // namespace theia
