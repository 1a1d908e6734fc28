// pbrt-v4's "loopsubdiv": topology (closed stays closed, V' = V + E, four
// triangles per triangle), the rules (planar stays planar, the limit mask of
// an interior vertex, the boundary crease rule), pbrt-v4's limit normals, and
// bad input as file:line errors.
#include "core/log.h"
#include "scene/loop_subdiv.h"
#include "scene/parser.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

using namespace theia;

namespace {

struct Control {
  std::vector<vec3> p;
  std::vector<uint32_t> indices;
};

TriangleMesh subdivide(const Control& c, int levels) {
  TriangleMesh m;
  std::string error;
  EXPECT_TRUE(loop_subdivide(c.p, c.indices, levels, &m, &error)) << error;
  return m;
}

// Wound counter-clockwise seen from outside (right-hand normals outward).
Control tetrahedron() {
  return {{vec3(1, 1, 1), vec3(1, -1, -1), vec3(-1, 1, -1), vec3(-1, -1, 1)}, {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2}};
}
Control cube() {
  Control c;
  for (int i = 0; i < 8; ++i) c.p.push_back(vec3(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1));
  c.indices = {0, 2, 3, 0, 3, 1,  4, 5, 7, 4, 7, 6,  0, 1, 5, 0, 5, 4,
               2, 6, 7, 2, 7, 3,  0, 4, 6, 0, 6, 2,  1, 3, 7, 1, 7, 5};
  return c;
}
Control octahedron() {
  Control c;
  c.p = {vec3(1, 0, 0), vec3(-1, 0, 0), vec3(0, 1, 0), vec3(0, -1, 0), vec3(0, 0, 1), vec3(0, 0, -1)};
  c.indices = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  return c;
}
Control reversed(Control c) {
  for (size_t t = 0; t < c.indices.size(); t += 3) std::swap(c.indices[t + 1], c.indices[t + 2]);
  return c;
}
// An n x n grid of quads on the plane z = 0.3 x - 0.2 y + 1, two triangles each.
Control grid(int n) {
  Control c;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) c.p.push_back(vec3(float(i), float(j), 0.3f * float(i) - 0.2f * float(j) + 1.0f));
  auto id = [&](int i, int j) { return uint32_t(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      c.indices.insert(c.indices.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j), id(i + 1, j + 1), id(i, j + 1)});
  return c;
}

// Undirected edge -> the directions it is used in (+1 for a < b, -1 otherwise).
std::map<std::pair<uint32_t, uint32_t>, std::vector<int>> edges_of(const TriangleMesh& m) {
  std::map<std::pair<uint32_t, uint32_t>, std::vector<int>> e;
  for (size_t t = 0; t < m.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      uint32_t a = m.indices[t + size_t(k)], b = m.indices[t + size_t(k + 1) % 3];
      e[{std::min(a, b), std::max(a, b)}].push_back(a < b ? 1 : -1);
    }
  return e;
}
std::set<uint32_t> boundary_vertices(const TriangleMesh& m) {
  std::set<uint32_t> b;
  for (const auto& [edge, uses] : edges_of(m))
    if (uses.size() == 1) b.insert({edge.first, edge.second});
  return b;
}

double loop_gamma(int n) {
  double beta = n == 3 ? 3.0 / 16.0 : 3.0 / (8.0 * n);
  return 1.0 / (n + 3.0 / (8.0 * beta));
}

std::string error_of(const std::string& shape) {
  try {
    parse_scene_string("WorldBegin\n" + shape, "test.pbrt");
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(LoopSubdiv, ClosedMeshesStayClosedAndVertexCountIsVPlusE) {
  for (const Control& c : {tetrahedron(), cube()}) {
    size_t v = c.p.size(), f = c.indices.size() / 3;
    for (int level = 0; level <= 4; ++level) {
      TriangleMesh m = subdivide(c, level);
      ASSERT_EQ(m.p.size(), v) << "level " << level;
      ASSERT_EQ(m.triangle_count(), f) << "level " << level;
      ASSERT_EQ(m.n.size(), m.p.size());
      auto edges = edges_of(m);
      for (const auto& [edge, uses] : edges) {
        ASSERT_EQ(uses.size(), 2u) << "edge " << edge.first << "-" << edge.second << " at level " << level;
        EXPECT_EQ(uses[0] + uses[1], 0) << "the two triangles run the edge opposite ways";
      }
      EXPECT_EQ(int64_t(v) - int64_t(edges.size()) + int64_t(f), 2) << "Euler characteristic of a sphere";
      v += edges.size();  // one new vertex per edge
      f *= 4;
    }
  }
}

TEST(LoopSubdiv, LevelZeroKeepsTheMeshAndPushesToTheLimit) {
  Control c = tetrahedron();
  TriangleMesh m = subdivide(c, 0);
  EXPECT_EQ(m.indices, c.indices);
  // Valence 3: beta = 3/16, gamma = 1/5: the vertex 2/5, each neighbour 1/5.
  for (size_t v = 0; v < 4; ++v) {
    vec3 want = 0.4f * c.p[v];
    for (size_t q = 0; q < 4; ++q)
      if (q != v) want += 0.2f * c.p[q];
    EXPECT_NEAR(glm::length(m.p[v] - want), 0.0f, 1e-6f) << v;
  }
  // On an open grid, boundary vertices take pbrt-v4's 1/5-3/5-1/5 mask along
  // the boundary; an interior regular vertex 1/12 per ring vertex.
  Control g = grid(2);
  TriangleMesh mg = subdivide(g, 0);
  vec3 side = 0.6f * g.p[1] + 0.2f * (g.p[0] + g.p[2]);
  EXPECT_NEAR(glm::length(mg.p[1] - side), 0.0f, 1e-6f);
  // The centre's ring is symmetric about it: its limit is itself.
  EXPECT_NEAR(glm::length(mg.p[4] - g.p[4]), 0.0f, 1e-6f);
}

TEST(LoopSubdiv, PlanarGridStaysPlanarWithNormalsAcrossIt) {
  Control c = grid(4);
  const vec3 plane_n = glm::normalize(vec3(-0.3f, 0.2f, 1.0f));  // upward, of z = 0.3 x - 0.2 y + 1
  for (int level : {1, 3}) {
    TriangleMesh m = subdivide(c, level);
    for (size_t v = 0; v < m.p.size(); ++v) {
      const vec3& p = m.p[v];
      EXPECT_NEAR(p.z, 0.3f * p.x - 0.2f * p.y + 1.0f, 2e-5f) << "vertex " << v;
      // pbrt-v4's limit normal: across the plane, against the right-hand
      // normal of the (counter-clockwise from +z) winding.
      vec3 n = glm::normalize(m.n[v]);
      EXPECT_NEAR(glm::dot(n, -plane_n), 1.0f, 1e-5f) << "vertex " << v;
    }
  }
}

// Interior vertices keep their index through every level and land where the
// Loop limit mask of the control mesh puts them: (1 - n gamma) p + gamma *
// (sum of the ring), which subdivision leaves unchanged.
TEST(LoopSubdiv, InteriorVertexLandsOnItsLimitMask) {
  for (int n : {3, 4, 5, 6, 7, 9}) {
    Control c;
    c.p.push_back(vec3(0.1f, -0.2f, 0.7f));
    for (int j = 0; j < n; ++j) {
      float a = 2.0f * kPi * float(j) / float(n);
      c.p.push_back(vec3((1.0f + 0.2f * float(j % 2)) * std::cos(a), std::sin(a), 0.3f * std::sin(3.0f * a)));
      c.indices.insert(c.indices.end(), {0u, uint32_t(1 + j), uint32_t(1 + (j + 1) % n)});
    }
    double gamma = loop_gamma(n);
    glm::dvec3 want = (1.0 - n * gamma) * glm::dvec3(c.p[0]);
    for (int j = 1; j <= n; ++j) want += gamma * glm::dvec3(c.p[size_t(j)]);
    if (n == 6) {
      EXPECT_DOUBLE_EQ(gamma, 1.0 / 12.0);
    }
    for (int level = 0; level <= 3; ++level) {
      TriangleMesh m = subdivide(c, level);
      EXPECT_NEAR(glm::length(glm::dvec3(m.p[0]) - want), 0.0, 2e-6) << "valence " << n << " level " << level;
      // The control ring winds counter-clockwise seen from +z: pbrt-v4's normal points down.
      EXPECT_LT(m.n[0].z, 0.0f);
    }
  }
}

// The crease rules use boundary vertices only: moving interior vertices
// leaves every boundary vertex where it was, on the boundary curve of the
// boundary polygon (here in the plane z = 0, on the line y = 0 where the
// polygon is straight).
TEST(LoopSubdiv, BoundaryVerticesFollowTheBoundaryCurveOnly) {
  Control flat = grid(4);
  for (vec3& p : flat.p) p.z = 0.0f;
  Control bumped = flat;
  for (size_t v = 0; v < bumped.p.size(); ++v) {
    vec3 p = bumped.p[v];
    bool boundary = p.x == 0 || p.y == 0 || p.x == 4 || p.y == 4;
    if (!boundary) bumped.p[v] += vec3(0.2f * std::sin(float(v)), 0.1f, 0.8f + 0.3f * std::cos(float(v)));
  }
  TriangleMesh a = subdivide(flat, 3), b = subdivide(bumped, 3);
  std::set<uint32_t> boundary = boundary_vertices(a);
  EXPECT_EQ(boundary.size(), size_t(16 * 8));  // 16 control boundary edges, each split in 8
  EXPECT_EQ(boundary, boundary_vertices(b));
  int straight = 0;
  for (uint32_t v : boundary) {
    EXPECT_EQ(a.p[v], b.p[v]) << "vertex " << v;
    EXPECT_EQ(b.p[v].z, 0.0f);
    // Between control x = 1 and 3 on y = 0 the four control points that
    // shape the curve are collinear.
    if (b.p[v].y < 0.5f && b.p[v].x >= 1.0f - 1e-4f && b.p[v].x <= 3.0f + 1e-4f) {
      EXPECT_NEAR(b.p[v].y, 0.0f, 1e-6f);
      ++straight;
    }
  }
  EXPECT_EQ(straight, 17);
  // Interior vertices did move.
  int moved = 0;
  for (size_t v = 0; v < a.p.size(); ++v) moved += a.p[v] != b.p[v];
  EXPECT_EQ(moved, int(a.p.size() - boundary.size()));
}

// pbrt-v4's limit normals point against the right-hand normal of the
// winding: outward on a closed convex mesh wound clockwise seen from
// outside, inward on one wound counter-clockwise.
TEST(LoopSubdiv, NormalsOnAClosedConvexMesh) {
  for (bool clockwise : {true, false}) {
    Control c = clockwise ? reversed(octahedron()) : octahedron();
    TriangleMesh m = subdivide(c, 3);
    int outward = 0;
    for (size_t v = 0; v < m.p.size(); ++v) {
      vec3 n = glm::normalize(m.n[v]), radial = glm::normalize(m.p[v]);
      // Close to radial on this nearly round surface.
      EXPECT_GT(std::abs(glm::dot(n, radial)), 0.9f) << v;
      outward += glm::dot(n, radial) > 0.0f;
    }
    EXPECT_EQ(outward, clockwise ? int(m.p.size()) : 0);
    // At the six original vertices the normal is exactly radial by symmetry.
    for (size_t v = 0; v < 6; ++v)
      EXPECT_NEAR(std::abs(glm::dot(glm::normalize(m.n[v]), glm::normalize(m.p[v]))), 1.0f, 1e-6f);
  }
}

TEST(LoopSubdiv, ParsedShapeIsABakedTriangleMesh) {
  Scene s = parse_scene_string(
      "WorldBegin\nTranslate 0 0 5\nReverseOrientation\nShape \"loopsubdiv\" \"integer levels\" 2 "
      "\"point3 P\" [1 1 1  1 -1 -1  -1 1 -1  -1 -1 1] \"integer indices\" [0 1 2  0 3 1  0 2 3  1 3 2]\n",
      "test.pbrt");
  ASSERT_EQ(s.shapes.size(), 1u);
  ASSERT_EQ(s.shapes[0].kind, ShapeKind::TriangleMesh);
  const TriangleMesh& m = s.meshes[size_t(s.shapes[0].mesh)];
  TriangleMesh object = subdivide(tetrahedron(), 2);
  ASSERT_EQ(m.p.size(), object.p.size());
  EXPECT_EQ(m.indices, object.indices);
  for (size_t v = 0; v < m.p.size(); ++v) {
    EXPECT_NEAR(glm::length(m.p[v] - (object.p[v] + vec3(0, 0, 5))), 0.0f, 1e-5f);
    // ReverseOrientation flips the normals, as pbrt-v4's TriangleMesh does.
    EXPECT_NEAR(glm::dot(glm::normalize(m.n[v]), -glm::normalize(object.n[v])), 1.0f, 1e-5f);
  }
  // levels defaults to 3.
  Scene d = parse_scene_string(
      "WorldBegin\nShape \"loopsubdiv\" \"point3 P\" [1 1 1  1 -1 -1  -1 1 -1  -1 -1 1] "
      "\"integer indices\" [0 1 2  0 3 1  0 2 3  1 3 2]\n",
      "test.pbrt");
  EXPECT_EQ(d.meshes[0].triangle_count(), 4u * 64u);
}

TEST(LoopSubdiv, BadInputIsAnErrorWithFileAndLine) {
  const std::string P = "\"point3 P\" [0 0 0  1 0 0  0 1 0  0 0 1  1 1 1] ";
  struct Case {
    std::string shape, message;
  };
  for (const Case& k : {
           Case{"Shape \"loopsubdiv\" " + P + "\"integer indices\" [0 1 2 3]", "expected a multiple of 3"},
           Case{"Shape \"loopsubdiv\" " + P + "\"integer indices\" [0 1 5]", "expected an index below the 5"},
           Case{"Shape \"loopsubdiv\" " + P + "\"integer indices\" [0 1 -1]", "expected an index below the 5"},
           Case{"Shape \"loopsubdiv\" " + P, "expected triangle vertex indices"},
           Case{"Shape \"loopsubdiv\" \"integer indices\" [0 1 2]", "expected vertex positions"},
           Case{"Shape \"loopsubdiv\" \"integer levels\" -1 " + P + "\"integer indices\" [0 1 2]", "expected 0 or more"},
           // Three triangles on the edge 0-1.
           Case{"Shape \"loopsubdiv\" " + P + "\"integer indices\" [0 1 2  1 0 3  0 1 4]", "manifold"},
           // Two triangles running the edge 0-1 the same way.
           Case{"Shape \"loopsubdiv\" " + P + "\"integer indices\" [0 1 2  0 1 3]", "consistently oriented"},
           // Two fans meeting at vertex 0 only.
           Case{"Shape \"loopsubdiv\" \"point3 P\" [0 0 0  1 0 0  0 1 0  -1 0 0  0 -1 0] "
                "\"integer indices\" [0 1 2  0 3 4]",
                "one fan"},
           Case{"Shape \"loopsubdiv\" " + P + "\"integer indices\" [0 1 1]", "three distinct vertices"},
       }) {
    std::string e = error_of(k.shape);
    EXPECT_NE(e.find("test.pbrt:2:"), std::string::npos) << e;
    EXPECT_NE(e.find(k.message), std::string::npos) << e;
    EXPECT_NE(e.find("expected"), std::string::npos) << e;
  }
}
