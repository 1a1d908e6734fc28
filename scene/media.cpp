#include "scene/media.h"

#include <algorithm>
#include <cmath>

namespace theia {

namespace {

float voxel(const Medium& m, int x, int y, int z) {
  if (x < 0 || y < 0 || z < 0 || x >= m.nx || y >= m.ny || z >= m.nz) return 0.0f;
  return m.density[(size_t(z) * size_t(m.ny) + size_t(y)) * size_t(m.nx) + size_t(x)];
}

// The distance to the next tentative collision at majorant rate sigma_maj.
float exponential_step(float sigma_maj, float u) { return -std::log1p(-u) / sigma_maj; }

// Walks the tentative collisions of `m` along `ray` in [0, tmax]: visit(s,
// point props, t) returns false to stop.  Returns true if the walk left the
// segment (no stop).
// Collisions at rate sigma_maj in [s, s_end]; false when visit stopped.
// Past s_end the walk restarts at s_end (the exponential is memoryless).
template <class Visit>
bool walk_span(const Medium& m, const MediumSegment& seg, double& s, double s_end, float sigma_maj, TrackingRng& rng,
               Visit& visit) {
  if (!(sigma_maj > 0.0f)) {
    s = s_end;
    return true;
  }
  while (true) {
    s += exponential_step(sigma_maj, rng.next());
    if (!(s < s_end)) {
      s = s_end;
      return true;
    }
    const vec3 p = seg.o + seg.d * float(s);
    if (!visit(medium_props(m, p), sigma_maj, float(s * double(seg.t_per_s)))) return false;
  }
}

// A grid's walk, cell by cell of its majorant grid (a 3D DDA), so that the
// collision rate follows the local density bound.
template <class Visit>
bool walk_grid(const Medium& m, const MediumSegment& seg, TrackingRng& rng, Visit& visit) {
  const int res = kMajorantGridRes;
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
  const float sigma_t_max = max_component(m.sigma_a + m.sigma_s);
  double s = seg.s0;
  while (true) {
    const int a = next[0] < next[1] ? (next[0] < next[2] ? 0 : 2) : (next[1] < next[2] ? 1 : 2);
    const double s_end = std::min(double(seg.s1), next[a]);
    const float majorant = m.majorants[(size_t(cell[2]) * res + size_t(cell[1])) * res + size_t(cell[0])];
    if (!walk_span(m, seg, s, s_end, sigma_t_max * majorant, rng, visit)) return false;
    if (s_end >= double(seg.s1)) return true;
    cell[a] += step[a];
    if (cell[a] < 0 || cell[a] >= res) return true;
    next[a] += delta[a];
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
  if (m.kind == MediumKind::UniformGrid && !m.majorants.empty()) return walk_grid(m, seg, rng, visit);
  double s = seg.s0;
  return walk_span(m, seg, s, double(seg.s1), medium_majorant(m), rng, visit);
}

float average(const RGB& c) { return (c.x + c.y + c.z) * (1.0f / 3.0f); }

}  // namespace

float medium_density(const Medium& m, const vec3& p) {
  if (m.kind == MediumKind::Homogeneous) return 1.0f;
  const vec3 u = (p - m.p0) / (m.p1 - m.p0);
  const vec3 g(u.x * float(m.nx) - 0.5f, u.y * float(m.ny) - 0.5f, u.z * float(m.nz) - 0.5f);
  const vec3 f = glm::floor(g);
  const int x = int(f.x), y = int(f.y), z = int(f.z);
  const vec3 d = g - f;
  auto lerp = [](float t, float a, float b) { return (1.0f - t) * a + t * b; };
  const float d00 = lerp(d.x, voxel(m, x, y, z), voxel(m, x + 1, y, z));
  const float d10 = lerp(d.x, voxel(m, x, y + 1, z), voxel(m, x + 1, y + 1, z));
  const float d01 = lerp(d.x, voxel(m, x, y, z + 1), voxel(m, x + 1, y, z + 1));
  const float d11 = lerp(d.x, voxel(m, x, y + 1, z + 1), voxel(m, x + 1, y + 1, z + 1));
  return lerp(d.z, lerp(d.y, d00, d10), lerp(d.y, d01, d11));
}

// pbrt-v4 scales a grid's Le by "Lescale" looked up in a 1 x 1 x 1 grid,
// trilinearly like the density: 1 at the box's centre, falling linearly to
// 1/2 at each face (a product over the axes).
float grid_emission_scale(const Medium& m, const vec3& p) {
  const vec3 u = (p - m.p0) / (m.p1 - m.p0);
  const vec3 f = glm::max(vec3(1.0f) - glm::abs(u - vec3(0.5f)), vec3(0.0f));
  return f.x * f.y * f.z;
}

MediumProps medium_props(const Medium& m, const vec3& p) {
  const float d = medium_density(m, p);
  if (m.kind == MediumKind::UniformGrid && !is_black(m.Le))
    return MediumProps{m.sigma_a * d, m.sigma_s * d, m.Le * grid_emission_scale(m, p)};
  return MediumProps{m.sigma_a * d, m.sigma_s * d, m.Le};
}

void build_majorant_grid(Medium& m) {
  const int res = kMajorantGridRes;
  m.majorants.assign(size_t(res) * res * res, 0.0f);
  const int n[3] = {m.nx, m.ny, m.nz};
  for (int z = 0; z < res; ++z)
    for (int y = 0; y < res; ++y)
      for (int x = 0; x < res; ++x) {
        // The voxels whose centres the trilinear lookup blends anywhere in the cell.
        const int c[3] = {x, y, z};
        int lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::max(int(std::floor(float(c[a]) / res * float(n[a]) - 0.5f)), 0);
          hi[a] = std::min(int(std::floor(float(c[a] + 1) / res * float(n[a]) - 0.5f)) + 1, n[a] - 1);
        }
        float v = 0.0f;
        for (int k = lo[2]; k <= hi[2]; ++k)
          for (int j = lo[1]; j <= hi[1]; ++j)
            for (int i = lo[0]; i <= hi[0]; ++i) v = std::max(v, voxel(m, i, j, k));
        m.majorants[(size_t(z) * res + size_t(y)) * res + size_t(x)] = v;
      }
}

float medium_majorant(const Medium& m) { return max_component(m.sigma_a + m.sigma_s) * m.max_density; }

MediumSegment medium_segment(const Medium& m, const Ray& ray, float t0, float t1) {
  MediumSegment seg;
  vec3 o = ray.o, d = ray.d;
  if (m.kind == MediumKind::UniformGrid) {
    const Transform medium_from_render = m.render_from_medium.inverse();
    o = medium_from_render.point(ray.o);
    d = medium_from_render.vector(ray.d);
  }
  const float len = glm::length(d);
  if (!(len > 0.0f) || !std::isfinite(len)) return seg;
  seg.o = o;
  seg.d = d / len;
  seg.t_per_s = 1.0f / len;
  // Distances in double: an unbounded segment (a ray that leaves the scene) stays infinite.
  double s0 = double(t0) * len, s1 = double(t1) * len;
  if (m.kind == MediumKind::UniformGrid) {
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

FreeFlight sample_free_flight(const Medium& m, const Ray& ray, float tmax, const RGB& beta_in, TrackingRng& rng) {
  FreeFlight ff;
  RGB beta = beta_in;
  const bool emissive = !is_black(m.Le);
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
