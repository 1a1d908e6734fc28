#include "scene/loop_subdiv.h"

#include <fmt/format.h>

#include <cmath>
#include <unordered_map>
#include <vector>

namespace theia {

namespace {

using glm::dvec3;

constexpr int next3(int i) { return (i + 1) % 3; }
constexpr int prev3(int i) { return (i + 2) % 3; }

// A triangle with its neighbours: f[k] is the triangle across the edge
// (v[k], v[k + 1]), -1 on the boundary.
struct SubdivFace {
  uint32_t v[3];
  int32_t f[3];
};

// One level of the subdivision mesh.  Vertex i's start_face is a triangle
// that uses it (-1: unreferenced).
struct SubdivMesh {
  std::vector<dvec3> p;
  std::vector<SubdivFace> faces;
  std::vector<int32_t> start_face;
};

int vnum(const SubdivFace& f, uint32_t v) {
  for (int k = 0; k < 3; ++k)
    if (f.v[k] == v) return k;
  return -1;  // unreachable on a mesh the adjacency check accepted
}

// Walking the fan of vertex v: next_face turns across the edge (v, next
// vertex), prev_face the other way.
int32_t next_face(const SubdivMesh& m, int32_t f, uint32_t v) { return m.faces[size_t(f)].f[vnum(m.faces[size_t(f)], v)]; }
int32_t prev_face(const SubdivMesh& m, int32_t f, uint32_t v) {
  return m.faces[size_t(f)].f[prev3(vnum(m.faces[size_t(f)], v))];
}

struct VertexRing {
  bool boundary = false;
  std::vector<uint32_t> ring;  // pbrt-v4's one-ring order; its size is the valence
};

// pbrt-v4's SDVertex::oneRing: interior rings follow next_face (clockwise seen
// from the side the winding's right-hand normal points to); boundary rings run
// from the last triangle's next vertex back along prev_face.
VertexRing one_ring(const SubdivMesh& m, uint32_t v) {
  VertexRing r;
  int32_t start = m.start_face[v];
  if (start < 0) return r;
  int32_t f = start;
  do {
    f = next_face(m, f, v);
  } while (f >= 0 && f != start);
  r.boundary = f < 0;
  if (!r.boundary) {
    f = start;
    do {
      const SubdivFace& face = m.faces[size_t(f)];
      r.ring.push_back(face.v[next3(vnum(face, v))]);
      f = next_face(m, f, v);
    } while (f != start);
    return r;
  }
  f = start;
  for (int32_t g; (g = next_face(m, f, v)) >= 0;) f = g;
  r.ring.push_back(m.faces[size_t(f)].v[next3(vnum(m.faces[size_t(f)], v))]);
  for (; f >= 0; f = prev_face(m, f, v)) r.ring.push_back(m.faces[size_t(f)].v[prev3(vnum(m.faces[size_t(f)], v))]);
  return r;
}

double loop_beta(size_t valence) { return valence == 3 ? 3.0 / 16.0 : 3.0 / (8.0 * double(valence)); }
double loop_gamma(size_t valence) { return 1.0 / (double(valence) + 3.0 / (8.0 * loop_beta(valence))); }

dvec3 weight_one_ring(const SubdivMesh& m, uint32_t v, const VertexRing& r, double beta) {
  dvec3 p = (1.0 - double(r.ring.size()) * beta) * m.p[v];
  for (uint32_t q : r.ring) p += beta * m.p[q];
  return p;
}
dvec3 weight_boundary(const SubdivMesh& m, uint32_t v, const VertexRing& r, double beta) {
  return (1.0 - 2.0 * beta) * m.p[v] + beta * (m.p[r.ring.front()] + m.p[r.ring.back()]);
}

// Links triangles across shared edges; false (with the reason) unless the
// mesh is manifold and consistently oriented.
bool build_adjacency(SubdivMesh& m, std::string* error) {
  std::unordered_map<uint64_t, uint32_t> directed;  // (a, b) -> 3 * face + edge
  directed.reserve(3 * m.faces.size());
  auto key = [](uint32_t a, uint32_t b) { return (uint64_t(a) << 32) | b; };
  std::vector<uint32_t> face_count(m.p.size(), 0);
  for (size_t fi = 0; fi < m.faces.size(); ++fi) {
    SubdivFace& f = m.faces[fi];
    if (f.v[0] == f.v[1] || f.v[1] == f.v[2] || f.v[2] == f.v[0]) {
      *error = fmt::format("triangle {} repeats vertex index (indices {} {} {}), expected three distinct vertices", fi,
                           f.v[0], f.v[1], f.v[2]);
      return false;
    }
    for (int k = 0; k < 3; ++k) {
      m.start_face[f.v[k]] = int32_t(fi);
      ++face_count[f.v[k]];
      uint32_t a = f.v[k], b = f.v[next3(k)];
      if (!directed.emplace(key(a, b), uint32_t(3 * fi + size_t(k))).second) {
        *error = fmt::format("edge {}-{} is used twice in the same direction (by triangles {} and {}), expected a "
                             "manifold, consistently oriented mesh",
                             a, b, directed[key(a, b)] / 3, fi);
        return false;
      }
      auto other = directed.find(key(b, a));
      if (other != directed.end()) {
        f.f[k] = int32_t(other->second / 3);
        m.faces[other->second / 3].f[other->second % 3] = int32_t(fi);
      }
    }
  }
  // Every triangle at a vertex must be in the fan one_ring walks.
  for (uint32_t v = 0; v < m.p.size(); ++v) {
    if (m.start_face[v] < 0) continue;
    VertexRing r = one_ring(m, v);
    size_t fan = r.boundary ? r.ring.size() - 1 : r.ring.size();
    if (fan != face_count[v]) {
      *error = fmt::format("vertex {} joins {} triangles that do not form one fan, expected a manifold mesh", v,
                           face_count[v]);
      return false;
    }
  }
  return true;
}

SubdivMesh refine(const SubdivMesh& m) {
  const size_t nv = m.p.size(), nf = m.faces.size();
  SubdivMesh r;
  r.p.resize(nv);
  r.start_face.assign(nv, -1);
  // Even vertices keep their index.
  for (uint32_t v = 0; v < nv; ++v) {
    if (m.start_face[v] < 0) {
      r.p[v] = m.p[v];
      continue;
    }
    VertexRing ring = one_ring(m, v);
    r.p[v] = ring.boundary ? weight_boundary(m, v, ring, 1.0 / 8.0)
                           : weight_one_ring(m, v, ring, loop_beta(ring.ring.size()));
    int32_t sf = m.start_face[v];
    r.start_face[v] = 4 * sf + vnum(m.faces[size_t(sf)], v);
  }
  // Odd vertices, numbered in the order the triangles first reach their edges.
  std::vector<uint32_t> edge_vert(3 * nf, UINT32_MAX);
  for (size_t fi = 0; fi < nf; ++fi) {
    const SubdivFace& f = m.faces[fi];
    for (int k = 0; k < 3; ++k) {
      if (edge_vert[3 * fi + size_t(k)] != UINT32_MAX) continue;
      uint32_t a = f.v[k], b = f.v[next3(k)];
      uint32_t odd = uint32_t(r.p.size());
      if (f.f[k] < 0) {
        r.p.push_back(0.5 * (m.p[a] + m.p[b]));
      } else {
        const SubdivFace& g = m.faces[size_t(f.f[k])];
        uint32_t c = f.v[prev3(k)], d = g.v[next3(vnum(g, a))];
        r.p.push_back(3.0 / 8.0 * (m.p[a] + m.p[b]) + 1.0 / 8.0 * (m.p[c] + m.p[d]));
        edge_vert[3 * size_t(f.f[k]) + size_t(vnum(g, b))] = odd;
      }
      edge_vert[3 * fi + size_t(k)] = odd;
      r.start_face.push_back(int32_t(4 * fi + 3));
    }
  }
  // Child k keeps corner k; child 3 is the middle triangle.  All keep the winding.
  r.faces.resize(4 * nf);
  for (size_t fi = 0; fi < nf; ++fi) {
    const SubdivFace& f = m.faces[fi];
    SubdivFace* c = &r.faces[4 * fi];
    int32_t base = int32_t(4 * fi);
    for (int k = 0; k < 3; ++k) {
      uint32_t odd = edge_vert[3 * fi + size_t(k)];
      c[k].v[k] = f.v[k];
      c[k].v[next3(k)] = odd;
      c[next3(k)].v[k] = odd;
      c[3].v[k] = odd;
      c[3].f[k] = base + next3(k);
      c[k].f[next3(k)] = base + 3;
      int32_t f2 = f.f[k], f3 = f.f[prev3(k)];
      c[k].f[k] = f2 >= 0 ? 4 * f2 + vnum(m.faces[size_t(f2)], f.v[k]) : -1;
      c[k].f[prev3(k)] = f3 >= 0 ? 4 * f3 + vnum(m.faces[size_t(f3)], f.v[k]) : -1;
    }
  }
  return r;
}

// pbrt-v4's limit tangents: Fourier weights round an interior ring, the
// boundary curve's chord and a valence-dependent cross-boundary stencil.
dvec3 limit_normal(const SubdivMesh& m, uint32_t v, const VertexRing& r) {
  const std::vector<uint32_t>& q = r.ring;
  const size_t n = q.size();
  dvec3 s(0.0), t(0.0);
  if (!r.boundary) {
    for (size_t j = 0; j < n; ++j) {
      double a = 2.0 * M_PI * double(j) / double(n);
      s += std::cos(a) * m.p[q[j]];
      t += std::sin(a) * m.p[q[j]];
    }
  } else {
    s = m.p[q[n - 1]] - m.p[q[0]];
    if (n == 2) {
      t = m.p[q[0]] + m.p[q[1]] - 2.0 * m.p[v];
    } else if (n == 3) {
      t = m.p[q[1]] - m.p[v];
    } else if (n == 4) {
      t = -m.p[q[0]] + 2.0 * m.p[q[1]] + 2.0 * m.p[q[2]] - m.p[q[3]] - 2.0 * m.p[v];
    } else {
      double theta = M_PI / double(n - 1);
      t = std::sin(theta) * (m.p[q[0]] + m.p[q[n - 1]]);
      for (size_t k = 1; k + 1 < n; ++k) t += (2.0 * std::cos(theta) - 2.0) * std::sin(double(k) * theta) * m.p[q[k]];
      t = -t;
    }
  }
  return glm::cross(s, t);
}

}  // namespace

bool loop_subdivide(std::span<const vec3> p, std::span<const uint32_t> indices, int levels, TriangleMesh* out,
                    std::string* error) {
  if (indices.size() % 3 != 0) {
    *error = fmt::format("{} indices, expected a multiple of 3", indices.size());
    return false;
  }
  for (uint32_t i : indices)
    if (i >= p.size()) {
      *error = fmt::format("index {}, expected an index below the {} vertices", i, p.size());
      return false;
    }
  SubdivMesh m;
  m.p.assign(p.begin(), p.end());
  m.start_face.assign(p.size(), -1);
  m.faces.resize(indices.size() / 3);
  for (size_t f = 0; f < m.faces.size(); ++f)
    m.faces[f] = SubdivFace{{indices[3 * f], indices[3 * f + 1], indices[3 * f + 2]}, {-1, -1, -1}};
  if (!build_adjacency(m, error)) return false;
  for (int level = 0; level < levels; ++level) m = refine(m);

  // Limit positions, then the normals from the rings of limit positions (as pbrt-v4 orders it).
  std::vector<VertexRing> rings(m.p.size());
  std::vector<dvec3> limit(m.p.size());
  for (uint32_t v = 0; v < m.p.size(); ++v) {
    rings[v] = one_ring(m, v);
    if (rings[v].ring.empty()) limit[v] = m.p[v];
    else if (rings[v].boundary) limit[v] = weight_boundary(m, v, rings[v], 1.0 / 5.0);
    else limit[v] = weight_one_ring(m, v, rings[v], loop_gamma(rings[v].ring.size()));
  }
  m.p = std::move(limit);
  *out = TriangleMesh{};
  out->p.resize(m.p.size());
  out->n.resize(m.p.size());
  for (uint32_t v = 0; v < m.p.size(); ++v) {
    out->p[v] = vec3(m.p[v]);
    out->n[v] = rings[v].ring.empty() ? vec3(0.0f) : vec3(limit_normal(m, v, rings[v]));
  }
  out->indices.reserve(3 * m.faces.size());
  for (const SubdivFace& f : m.faces) out->indices.insert(out->indices.end(), {f.v[0], f.v[1], f.v[2]});
  return true;
}

bool loop_subdiv_from_params(const ParamList& params, const SourceLoc& loc, TriangleMesh* out) {
  const Param* P = params.find("P", ParamType::Point3);
  if (!P) throw_at(loc, "loopsubdiv without \"point3 P\", expected vertex positions");
  const Param* ind = params.find("indices", ParamType::Integer);
  if (!ind) throw_at(loc, "loopsubdiv without \"integer indices\", expected triangle vertex indices");
  if (P->numbers.size() % 3 != 0)
    throw_at(P->loc, "{} has {} values, expected a multiple of 3", P->label(), P->numbers.size());
  if (ind->numbers.size() % 3 != 0)
    throw_at(ind->loc, "{} has {} values, expected a multiple of 3", ind->label(), ind->numbers.size());
  std::vector<vec3> p(P->numbers.size() / 3);
  for (size_t i = 0; i < p.size(); ++i)
    p[i] = vec3(float(P->numbers[3 * i]), float(P->numbers[3 * i + 1]), float(P->numbers[3 * i + 2]));
  std::vector<uint32_t> indices(ind->numbers.size());
  for (size_t i = 0; i < indices.size(); ++i) {
    double v = ind->numbers[i];
    if (!(v >= 0 && v < double(p.size())))
      throw_at(ind->loc, "index {} in {}, expected an index below the {} vertices", v, ind->label(), p.size());
    indices[i] = uint32_t(v);
  }
  int levels = 3;
  if (const Param* l = params.find("levels", ParamType::Integer)) {
    levels = int(l->numbers.empty() ? 3 : l->numbers[0]);
    if (levels < 0) throw_at(l->loc, "{} is {}, expected 0 or more", l->label(), levels);
    // Each level quadruples the triangles: 12 levels turn one triangle into 16.7 million.
    if (levels > 12) throw_at(l->loc, "{} is {}, expected at most 12", l->label(), levels);
  }
  if (indices.empty()) {
    warn_at(loc, "loopsubdiv has no triangles; shape ignored");
    return false;
  }
  std::string error;
  if (!loop_subdivide(p, indices, levels, out, &error)) throw_at(ind->loc, "loopsubdiv: {}", error);
  return true;
}

}  // namespace theia
