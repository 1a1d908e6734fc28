#include "scene/accel.h"

#include "core/hash.h"
#include "core/log.h"
#include "scene/shape_bounds.h"
#include "scene/shapes.h"
#include "scene/surface_crossing.h"
#include "scene/texture.h"

#include <embree3/rtcore.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace theia {

static_assert(sizeof(vec3) == 3 * sizeof(float), "vertex arrays are shared with Embree as packed float3");
static_assert(kInvalidId == RTC_INVALID_GEOMETRY_ID);

namespace {

// A sphere, disk or cylinder as an Embree user geometry: intersected in object space,
// in double precision, with the transform kept exactly as the scene gave it.
struct QuadricGeom {
  ShapeKind kind;
  SphereShape sphere;
  DiskShape disk;
  CylinderShape cylinder;
  glm::dmat4 object_from_parent;  // parent = render space, or the prototype's space
  Bounds3 bounds;                 // in parent space
  bool never_occludes = false;    // a virtual light or an interface
  const Scene* scene = nullptr;
  int alpha = -1;                 // float texture index: cut-outs, or -1
};

// The context every query passes: rays carry their index in the span
// (RTCRay::id) so filters can find what travels beside them, whatever packets
// Embree regroups them into.
// What intersect_passing's context filter keeps: the passing hits it
// rejects (shape_passes, by shape index), the nearest of them and their count.
struct PassingLog {
  const Accel* accel;
  const std::vector<uint8_t>* shape_passes;
  Hit first;
  uint32_t count = 0;
};

struct TraceContext {
  RTCIntersectContext rtc;
  const PrimRef* skips = nullptr;  // the curve segment each ray left, or none at all
  bool surface = true;             // false: hits need only t (quadrics may leave u, v at 0)
  PassingLog* passing = nullptr;   // intersect_passing's log, with rtc.filter = record_passing
};

// intersect_passing's context filter (run after a geometry's own, so only
// on hits an alpha cut-out or a curve's skip kept): a hit on a passing shape
// is logged and rejected, so that the trace goes on to what lies beyond.
void record_passing(const RTCFilterFunctionNArguments* args) {
  PassingLog& log = *reinterpret_cast<const TraceContext*>(args->context)->passing;
  const unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    Hit h;
    h.geom = RTCHitN_geomID(args->hit, n, i);
    h.inst = RTCHitN_instID(args->hit, n, i, 0);
    const int shape = log.accel->shape_index(h);
    if (shape < 0 || !(*log.shape_passes)[size_t(shape)]) continue;
    h.t = RTCRayN_tfar(args->ray, n, i);
    h.u = RTCHitN_u(args->hit, n, i);
    h.v = RTCHitN_v(args->hit, n, i);
    h.prim = RTCHitN_primID(args->hit, n, i);
    if (h.t < log.first.t) log.first = h;
    ++log.count;
    args->valid[i] = 0;
  }
}

// Virtual lights and interfaces do not block: shadow rays ignore every hit on
// them.  (Closest-hit rays do stop there; the engine splats a virtual light's
// emission and re-traces from the far side.)
void reject_occlusion(const RTCFilterFunctionNArguments* args) {
  for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
}

uint32_t float_bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

// pbrt-v4's stochastic alpha test: a hit where alpha < 1 is kept with
// probability alpha, decided by a hash of the ray and `salt` (what tells hits
// along one ray apart) so that the answer is a pure function of the query
// (deterministic, and the same for the closest-hit and the shadow query along
// one ray).  alpha <= 0 never keeps a hit.  o, d and t in the space the hit
// was found in; uv is the hit's texture coordinates.
bool alpha_keeps_hit(const Scene& scene, int alpha, vec2 uv, const vec3& o, const vec3& d, float t, uint32_t salt) {
  float a = eval_float_texture(scene, alpha, TextureEvalContext{uv, o + t * d});
  if (a >= 1.0f) return true;
  float u = a <= 0.0f ? 1.0f
                      : to_unit_float(uint32_t(hash(float_bits(o.x), float_bits(o.y), float_bits(o.z), float_bits(d.x),
                                                    float_bits(d.y), float_bits(d.z), salt) >> 32));
  return !(u >= a);  // (a NaN alpha keeps the hit)
}

bool quadric_intersect_once(const QuadricGeom& g, const glm::dvec3& o, const glm::dvec3& d, double tmin, double tmax,
                            QuadricHit* hit, bool surface) {
  switch (g.kind) {
    case ShapeKind::Sphere: return intersect_sphere(g.sphere, o, d, tmin, tmax, hit, surface);
    case ShapeKind::Cylinder: return intersect_cylinder(g.cylinder, o, d, tmin, tmax, hit, surface);
    default: return intersect_disk(g.disk, o, d, tmin, tmax, hit);
  }
}

vec2 quadric_uv(const QuadricGeom& g, const QuadricHit& hit) {
  switch (g.kind) {
    case ShapeKind::Sphere: return sphere_uv(g.sphere, hit.u, hit.v);
    case ShapeKind::Cylinder: return cylinder_uv(g.cylinder, hit.u, hit.v);
    default: return disk_uv(g.disk, hit.u, hit.v);
  }
}

// The closest hit in (tmin, tmax) that survives the alpha test: where the
// first root is cut out the ray goes on to the second.  The hit distance
// salts the test, so the two roots (and two quadrics) decide independently.
// `surface` false: the caller needs only t (the alpha test still gets its uv).
bool quadric_hit(const QuadricGeom& g, const glm::dvec3& o_parent, const glm::dvec3& d_parent, double tmin,
                 double tmax, QuadricHit* hit, bool surface) {
  glm::dvec3 o = glm::dvec3(g.object_from_parent * glm::dvec4(o_parent, 1.0));
  glm::dvec3 d = glm::dmat3(g.object_from_parent) * d_parent;
  surface = surface || g.alpha >= 0;
  // Each pass finds a root strictly past the last one: at most two passes.
  while (quadric_intersect_once(g, o, d, tmin, tmax, hit, surface)) {
    if (g.alpha < 0) return true;
    vec2 uv = quadric_uv(g, *hit);
    float t = float(hit->t);
    if (alpha_keeps_hit(*g.scene, g.alpha, uv, vec3(o_parent), vec3(d_parent), t, float_bits(t))) return true;
    tmin = hit->t;
  }
  return false;
}

void quadric_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* g = static_cast<const QuadricGeom*>(args->geometryUserPtr);
  RTCBounds* b = args->bounds_o;
  b->lower_x = g->bounds.min.x, b->lower_y = g->bounds.min.y, b->lower_z = g->bounds.min.z;
  b->upper_x = g->bounds.max.x, b->upper_y = g->bounds.max.y, b->upper_z = g->bounds.max.z;
}

void quadric_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* g = static_cast<const QuadricGeom*>(args->geometryUserPtr);
  // A sphere or cylinder at top level leaves its (u, v) to compute_interaction
  // (Accel::quadric_uv, from the same ray): most hits in a dense medium, or
  // behind a closer one, are never shaded, and their atan2 and acos were a
  // tenth of a render.  Inside an instance the ray is Embree's float
  // transform of it, which the lazy path could not repeat bit for bit.
  const bool lazy = g->kind != ShapeKind::Disk && args->context->instID[0] == RTC_INVALID_GEOMETRY_ID;
  const bool surface = reinterpret_cast<const TraceContext*>(args->context)->surface && !lazy;
  unsigned n = args->N;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, n);
  RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, n);
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] != -1) continue;
    glm::dvec3 o(RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i), RTCRayN_org_z(ray, n, i));
    glm::dvec3 d(RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i), RTCRayN_dir_z(ray, n, i));
    QuadricHit qh;
    if (!quadric_hit(*g, o, d, RTCRayN_tnear(ray, n, i), RTCRayN_tfar(ray, n, i), &qh, surface)) continue;
    RTCRayN_tfar(ray, n, i) = float(qh.t);
    RTCHitN_u(hit, n, i) = lazy ? kQuadricUVPending : qh.u;
    RTCHitN_v(hit, n, i) = qh.v;
    // Ng is not used by theia (compute_interaction rebuilds it), but keep it sane.
    RTCHitN_Ng_x(hit, n, i) = 0.0f;
    RTCHitN_Ng_y(hit, n, i) = 0.0f;
    RTCHitN_Ng_z(hit, n, i) = 1.0f;
    RTCHitN_primID(hit, n, i) = args->primID;
    RTCHitN_geomID(hit, n, i) = args->geomID;
    RTCHitN_instID(hit, n, i, 0) = args->context->instID[0];
  }
}

void quadric_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* g = static_cast<const QuadricGeom*>(args->geometryUserPtr);
  if (g->never_occludes) return;
  unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] != -1) continue;
    glm::dvec3 o(RTCRayN_org_x(args->ray, n, i), RTCRayN_org_y(args->ray, n, i), RTCRayN_org_z(args->ray, n, i));
    glm::dvec3 d(RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i), RTCRayN_dir_z(args->ray, n, i));
    QuadricHit qh;
    if (quadric_hit(*g, o, d, RTCRayN_tnear(args->ray, n, i), RTCRayN_tfar(args->ray, n, i), &qh, false))
      RTCRayN_tfar(args->ray, n, i) = -kInfinity;
  }
}

// What Embree's filter functions need: a triangle mesh with an "alpha"
// texture (cut-outs), or any curve (cut-outs, and skipping the segment a ray
// was spawned from).  Meshes without alpha get no filter and pay nothing.
struct FilterGeom {
  const Scene* scene;
  const TriangleMesh* mesh;  // nullptr for curves, whose texture uv is the hit's (u, v)
  const CurveSet* curve;     // nullptr for meshes
  int alpha;                 // float texture index, or -1
};

// A hit on the curve segment the ray left, within kCurveSkipWidths of its
// widest width of the origin (distances in the curve's space, where Embree
// reports t with the ray's own direction).
bool is_spawn_self_hit(const FilterGeom& g, const RTCFilterFunctionNArguments* args, unsigned i, uint32_t prim) {
  const unsigned n = args->N;
  const PrimRef* skips = reinterpret_cast<const TraceContext*>(args->context)->skips;
  if (!skips) return false;
  const PrimRef& skip = skips[RTCRayN_id(args->ray, n, i)];
  if (skip.prim != prim || skip.geom != RTCHitN_geomID(args->hit, n, i) ||
      skip.inst != RTCHitN_instID(args->hit, n, i, 0))
    return false;
  const vec4* q = &g.curve->cp[4 * size_t(prim)];
  float width = 2.0f * std::max({q[0].w, q[1].w, q[2].w, q[3].w});
  vec3 d(RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i), RTCRayN_dir_z(args->ray, n, i));
  return RTCRayN_tfar(args->ray, n, i) * glm::length(d) < kCurveSkipWidths * width;
}

// Triangles and curve segments tell their alpha decisions apart by primitive.
void hit_filter(const RTCFilterFunctionNArguments* args) {
  const auto* g = static_cast<const FilterGeom*>(args->geometryUserPtr);
  const unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    uint32_t prim = RTCHitN_primID(args->hit, n, i);
    if (g->curve && is_spawn_self_hit(*g, args, i, prim)) {
      args->valid[i] = 0;
      continue;
    }
    if (g->alpha < 0) continue;
    float b1 = RTCHitN_u(args->hit, n, i), b2 = RTCHitN_v(args->hit, n, i);
    vec3 o(RTCRayN_org_x(args->ray, n, i), RTCRayN_org_y(args->ray, n, i), RTCRayN_org_z(args->ray, n, i));
    vec3 d(RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i), RTCRayN_dir_z(args->ray, n, i));
    vec2 hit_uv(b1, b2);
    if (g->mesh) {
      vec2 uv[3];
      triangle_uvs(*g->mesh, prim, uv);
      hit_uv = (1.0f - b1 - b2) * uv[0] + b1 * uv[1] + b2 * uv[2];
    }
    if (!alpha_keeps_hit(*g->scene, g->alpha, hit_uv, o, d, RTCRayN_tfar(args->ray, n, i), prim)) args->valid[i] = 0;
  }
}

// Embree traces a flat curve as a chain of `rate` ray-facing quads per
// segment, on chords between curve points at uniform u (documented: flat
// curves are approximate by design; no flag changes that): a chord of
// parameter length 1/rate strays from the curve by at most max|c''| / (8 rate^2).
// The rate keeps that within kFlatCurveSag of each segment's width, from
// Embree's default 4 (cheapest) up to kFlatCurveMaxRate, where Embree stops:
// rates 16, 32, 64 and 128 gave bit-identical hits (Embree 3.13.5).
float flat_curve_tessellation_rate(const CurveSet& c) {
  float rate = 4.0f;
  for (size_t k = 0; k < c.segment_count(); ++k) {
    const vec4* q = &c.cp[4 * k];
    float width = 2.0f * std::max({q[0].w, q[1].w, q[2].w, q[3].w});
    vec3 a0 = vec3(q[2]) - 2.0f * vec3(q[1]) + vec3(q[0]), a1 = vec3(q[3]) - 2.0f * vec3(q[2]) + vec3(q[1]);
    float c2 = 6.0f * std::max(glm::length(a0), glm::length(a1));  // max |c''| (linear in u)
    if (width > 0.0f) rate = std::max(rate, std::ceil(std::sqrt(c2 / (8.0f * kFlatCurveSag * width))));
  }
  return std::min(rate, kFlatCurveMaxRate);
}

}  // namespace

// The widest ray packet this Embree build traces natively on this CPU, 1
// when it was built without packets (intersect then traces coherent rays one
// by one as well).
static int native_packet_width(RTCDevice device) {
  if (rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED)) return 16;
  if (rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED)) return 8;
  if (rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED)) return 4;
  return 1;
}

struct Accel::Impl {
  RTCDevice device = nullptr;
  RTCScene top = nullptr;
  std::vector<RTCScene> prototypes;
  std::deque<QuadricGeom> quadrics;  // stable addresses: Embree holds pointers to them
  std::deque<FilterGeom> filter_geoms; // likewise
  size_t curve_bytes = 0;            // curve control points (shared from the Scene) and index buffers; Embree's monitor counts the normals
  std::deque<std::vector<uint32_t>> curve_indices;  // stable: Embree shares them
  std::vector<int> top_shape;        // top-level geometry id -> shape index (-1 for instances)
  std::vector<int> top_instance;     // top-level geometry id -> instance index (-1 for shapes)
  std::vector<const QuadricGeom*> top_quadric;  // top-level geometry id -> its quadric, or nullptr
  std::vector<std::vector<int>> proto_shape;  // prototype -> geometry id -> shape index
  std::vector<int> instance_prototype;        // Scene instance -> prototype
  std::vector<uint8_t> shape_passes;          // Scene shape -> shape_crossing says Passes (intersect_passing)
  std::vector<std::vector<vec3>> passing_normals;  // Scene shape -> its triangles' unit normals, if it passes
  std::vector<glm::dmat4> render_from_instance, instance_from_render;  // per Scene instance
  std::atomic<int64_t> embree_bytes{0};
  std::atomic<int64_t> embree_peak{0};
  int packet_width = 1;  // the widest packet Embree traces natively here (16, 8, 4), 1 for none
  std::mutex error_mutex;
  std::string first_error;

  ~Impl() {
    if (top) rtcReleaseScene(top);
    for (RTCScene s : prototypes)
      if (s) rtcReleaseScene(s);
    if (device) rtcReleaseDevice(device);
  }

  void check(const char* what) {
    std::lock_guard lock(error_mutex);
    if (!first_error.empty()) throw_error("Embree failed while {}: {}", what, first_error);
  }
  RTCScene new_scene() {
    RTCScene s = rtcNewScene(device);
    // Robust mode, by measurement (Embree 3.13.5, this machine): rays from
    // inside a closed tetrahedron aimed at its vertices and edges leaked 15% of
    // the time without it and never with it, while incoherent tracing of a
    // 432k-triangle scene slowed by only ~3% (1.75 -> 1.69 Mrays/s per core).
    // The context filter flag: intersect_passing's trace sets one (others
    // leave it null and pay a pointer test per hit).
    rtcSetSceneFlags(s, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneBuildQuality(s, RTC_BUILD_QUALITY_HIGH);
    return s;
  }
  // Attaches shape `index` to `scene`; returns the geometry id or kInvalidId
  // when the shape has nothing to trace.
  uint32_t add_shape(RTCScene scene, const Scene& sc, int index);
  RTCGeometry new_curve_geometry(const Scene& sc, const Shape& s);
};

static const char* rtc_error_name(RTCError e) {
  switch (e) {
    case RTC_ERROR_NONE: return "no error";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
    default: return "unknown error";
  }
}

// One Embree curve geometry per shape, a primitive per cubic Bezier segment.
RTCGeometry Accel::Impl::new_curve_geometry(const Scene& sc, const Shape& s) {
  if (s.curves < 0 || size_t(s.curves) >= sc.curves.size())
    throw_error("{}:{}: curve shape names curve set {}, which does not exist", s.loc.file, s.loc.line, s.curves);
  const CurveSet& c = sc.curves[size_t(s.curves)];
  if (c.segment_count() == 0) return nullptr;
  RTCGeometryType type = c.type == CurveType::Flat       ? RTC_GEOMETRY_TYPE_FLAT_BEZIER_CURVE
                         : c.type == CurveType::Cylinder ? RTC_GEOMETRY_TYPE_ROUND_BEZIER_CURVE
                                                         : RTC_GEOMETRY_TYPE_NORMAL_ORIENTED_BEZIER_CURVE;
  RTCGeometry geom = rtcNewGeometry(device, type);
  if (c.type == CurveType::Flat) rtcSetGeometryTessellationRate(geom, flat_curve_tessellation_rate(c));
  // (x, y, z, r) float4 records: no read past the last one, so the Scene's array is shared.
  rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, c.cp.data(), 0, sizeof(vec4),
                             c.cp.size());
  std::vector<uint32_t>& idx = curve_indices.emplace_back(c.segment_count());
  for (size_t k = 0; k < idx.size(); ++k) idx[k] = uint32_t(4 * k);
  curve_bytes += idx.size() * sizeof(uint32_t) + c.cp.size() * sizeof(vec4);
  rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, idx.data(), 0, sizeof(uint32_t),
                             idx.size());
  if (c.type == CurveType::Ribbon) {
    if (c.n.size() != c.cp.size())
      throw_error("{}:{}: ribbon curve has {} normals for {} control points", s.loc.file, s.loc.line, c.n.size(),
                  c.cp.size());
    // Packed float3 may be read 16 bytes at a time: Embree's own padded buffer.
    void* dst = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_NORMAL, 0, RTC_FORMAT_FLOAT3, sizeof(vec3), c.n.size());
    if (dst) std::memcpy(dst, c.n.data(), c.n.size() * sizeof(vec3));
  }
  filter_geoms.push_back(FilterGeom{&sc, nullptr, &c, s.alpha});
  rtcSetGeometryUserData(geom, &filter_geoms.back());
  rtcSetGeometryIntersectFilterFunction(geom, hit_filter);
  rtcSetGeometryOccludedFilterFunction(geom, hit_filter);
  return geom;
}

uint32_t Accel::Impl::add_shape(RTCScene scene, const Scene& sc, int index) {
  const Shape& s = sc.shapes.at(size_t(index));
  // Shadow rays pass virtual lights and "interface" surfaces (a medium boundary that does not
  // scatter: pbrt-v4's shadow rays go on through a surface without a material).  Closest-hit
  // rays still stop at both; the engine continues them.
  const bool is_virtual = s.area_light >= 0 && size_t(s.area_light) < sc.lights.size() &&
                          sc.lights[size_t(s.area_light)].is_virtual;
  const bool is_interface = s.material >= 0 && size_t(s.material) < sc.materials.size() &&
                            sc.materials[size_t(s.material)].kind == MaterialKind::Interface;
  const bool never_occludes = is_virtual || is_interface;
  RTCGeometry geom = nullptr;
  if (s.kind == ShapeKind::TriangleMesh) {
    if (s.mesh < 0 || size_t(s.mesh) >= sc.meshes.size())
      throw_error("{}:{}: shape {} names mesh {}, which does not exist", s.loc.file, s.loc.line, index, s.mesh);
    const TriangleMesh& m = sc.meshes[size_t(s.mesh)];
    if (m.indices.size() % 3 != 0)
      throw_error("{}:{}: triangle mesh has {} indices, not a multiple of 3", s.loc.file, s.loc.line,
                  m.indices.size());
    for (uint32_t i : m.indices)
      if (i >= m.p.size())
        throw_error("{}:{}: triangle mesh index {} out of range (mesh has {} vertices)", s.loc.file, s.loc.line, i,
                    m.p.size());
    if (m.triangle_count() == 0) return kInvalidId;
    geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    // Embree loads the last vertex with a 16-byte load: share the array when the
    // vector's storage extends past it, copy into Embree's padded buffer otherwise.
    if (m.p.capacity() > m.p.size()) {
      rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, m.p.data(), 0, sizeof(vec3),
                                 m.p.size());
    } else {
      void* dst = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, sizeof(vec3), m.p.size());
      if (dst) std::memcpy(dst, m.p.data(), m.p.size() * sizeof(vec3));
    }
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m.indices.data(), 0,
                               3 * sizeof(uint32_t), m.triangle_count());
    if (s.alpha >= 0) {
      // Only meshes that have an alpha texture pay for the filter calls.
      filter_geoms.push_back(FilterGeom{&sc, &m, nullptr, s.alpha});
      rtcSetGeometryUserData(geom, &filter_geoms.back());
      rtcSetGeometryIntersectFilterFunction(geom, hit_filter);
      if (!never_occludes) rtcSetGeometryOccludedFilterFunction(geom, hit_filter);
    }
    // A virtual light or an interface never occludes, cut-out or not.
    if (never_occludes) rtcSetGeometryOccludedFilterFunction(geom, reject_occlusion);
  } else if (s.kind == ShapeKind::Curve) {
    // Curves never carry area lights (the parser drops them), so never virtual ones.
    geom = new_curve_geometry(sc, s);
    if (!geom) return kInvalidId;
    if (is_interface) rtcSetGeometryOccludedFilterFunction(geom, reject_occlusion);
  } else {
    QuadricGeom& q = quadrics.emplace_back();
    q.kind = s.kind;
    q.sphere = make_sphere_shape(s.sphere);
    q.disk = make_disk_shape(s.disk);
    q.cylinder = make_cylinder_shape(s.cylinder);
    glm::dmat4 parent_from_object(s.render_from_object.m);
    q.object_from_parent = glm::inverse(parent_from_object);
    q.bounds = transform_bounds(parent_from_object, quadric_object_bounds(s));
    q.never_occludes = never_occludes;
    // Cut-outs are tested inside the intersect and occluded functions (user
    // geometry gets no filter calls of its own), so a cut-out first root can
    // pass the ray on to the second.
    q.scene = &sc;
    q.alpha = s.alpha;
    geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geom, 1);
    rtcSetGeometryUserData(geom, &q);
    rtcSetGeometryBoundsFunction(geom, quadric_bounds, nullptr);
    rtcSetGeometryIntersectFunction(geom, quadric_intersect);
    rtcSetGeometryOccludedFunction(geom, quadric_occluded);
  }
  rtcCommitGeometry(geom);
  uint32_t id = rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  check("adding a shape");
  return id;
}

Accel::Accel(const Scene& scene) : impl_(std::make_unique<Impl>()) {
  auto start = std::chrono::steady_clock::now();
  Impl& I = *impl_;
  I.device = rtcNewDevice(nullptr);
  if (!I.device) throw_error("Embree could not create a device: {}", rtc_error_name(rtcGetDeviceError(nullptr)));
  I.packet_width = native_packet_width(I.device);
  rtcSetDeviceErrorFunction(
      I.device,
      [](void* user, RTCError code, const char* str) {
        // Exceptions must not cross Embree's C frames: record, and throw at the next check().
        auto* impl = static_cast<Impl*>(user);
        std::lock_guard lock(impl->error_mutex);
        std::string msg = fmt::format("{} ({})", str ? str : "", rtc_error_name(code));
        if (impl->first_error.empty()) impl->first_error = msg;
        log_warning("Embree: {}", msg);
      },
      &I);
  rtcSetDeviceMemoryMonitorFunction(
      I.device,
      [](void* user, ssize_t bytes, bool) -> bool {
        auto* impl = static_cast<Impl*>(user);
        int64_t now = impl->embree_bytes.fetch_add(bytes) + bytes;
        int64_t peak = impl->embree_peak.load();
        while (now > peak && !impl->embree_peak.compare_exchange_weak(peak, now)) {
        }
        return true;
      },
      &I);

  I.shape_passes.assign(scene.shapes.size(), 0);
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& s = scene.shapes[i];
    const bool known = (s.material < 0 || size_t(s.material) < scene.materials.size()) &&
                       (s.area_light < 0 || size_t(s.area_light) < scene.lights.size());
    I.shape_passes[i] = known && shape_crossing(scene, int(i)) == ShapeCrossing::Passes ? 1 : 0;
  }
  I.passing_normals.resize(scene.shapes.size());
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& s = scene.shapes[i];
    if (!I.shape_passes[i] || s.kind != ShapeKind::TriangleMesh || s.mesh < 0) continue;
    const TriangleMesh& m = scene.meshes[size_t(s.mesh)];
    I.passing_normals[i].resize(m.triangle_count());
    for (size_t t = 0; t < m.triangle_count(); ++t) I.passing_normals[i][t] = triangle_unit_normal(m, t);
  }

  // Prototypes first: instances need their committed scenes.
  I.prototypes.assign(scene.prototypes.size(), nullptr);
  I.proto_shape.resize(scene.prototypes.size());
  for (size_t p = 0; p < scene.prototypes.size(); ++p) {
    I.prototypes[p] = I.new_scene();
    for (int s : scene.prototypes[p].shapes) {
      uint32_t id = I.add_shape(I.prototypes[p], scene, s);
      if (id == kInvalidId) continue;
      if (I.proto_shape[p].size() <= id) I.proto_shape[p].resize(id + 1, -1);
      I.proto_shape[p][id] = s;
    }
    rtcCommitScene(I.prototypes[p]);
    I.check("building an object prototype");
  }

  I.top = I.new_scene();
  auto record = [&](uint32_t id, int shape, int instance) {
    if (I.top_shape.size() <= id) {
      I.top_shape.resize(id + 1, -1);
      I.top_instance.resize(id + 1, -1);
    }
    I.top_shape[id] = shape;
    I.top_instance[id] = instance;
    if (I.top_quadric.size() <= id) I.top_quadric.resize(id + 1, nullptr);
    if (shape >= 0 && scene.shapes[size_t(shape)].kind != ShapeKind::TriangleMesh &&
        scene.shapes[size_t(shape)].kind != ShapeKind::Curve)
      I.top_quadric[id] = &I.quadrics.back();
  };
  for (int s : scene.top_level_shapes) {
    uint32_t id = I.add_shape(I.top, scene, s);
    if (id != kInvalidId) record(id, s, -1);
  }
  I.instance_prototype.assign(scene.instances.size(), -1);
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.prototype < 0 || size_t(inst.prototype) >= scene.prototypes.size())
      throw_error("object instance {} names prototype {}, which does not exist", i, inst.prototype);
    I.instance_prototype[i] = inst.prototype;
    I.render_from_instance.push_back(glm::dmat4(inst.render_from_instance.m));
    I.instance_from_render.push_back(glm::inverse(I.render_from_instance.back()));
    if (I.proto_shape[size_t(inst.prototype)].empty()) continue;  // nothing to trace
    RTCGeometry geom = rtcNewGeometry(I.device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(geom, I.prototypes[size_t(inst.prototype)]);
    rtcSetGeometryTransform(geom, 0, RTC_FORMAT_FLOAT4X4_COLUMN_MAJOR, &inst.render_from_instance.m[0][0]);
    rtcCommitGeometry(geom);
    uint32_t id = rtcAttachGeometry(I.top, geom);
    rtcReleaseGeometry(geom);
    I.check("adding an object instance");
    record(id, -1, int(i));
  }
  rtcCommitScene(I.top);
  I.check("building the scene");

  double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  log_info("accel: {} shapes, {} prototypes, {} instances built in {:.1f} ms, {:.2f} MiB (build peak {:.2f} MiB){}",
           scene.top_level_shapes.size(), scene.prototypes.size(), scene.instances.size(), ms,
           double(memory_bytes()) / (1024.0 * 1024.0), double(I.embree_peak.load()) / (1024.0 * 1024.0),
           I.curve_bytes ? fmt::format(", curves {:.2f} MiB", double(I.curve_bytes) / (1024.0 * 1024.0)) : "");
}

Accel::~Accel() = default;

static void fill_ray(const Ray& r, uint32_t index, RTCRay& out) {
  out.org_x = r.o.x, out.org_y = r.o.y, out.org_z = r.o.z;
  out.tnear = r.tmin;
  out.dir_x = r.d.x, out.dir_y = r.d.y, out.dir_z = r.d.z;
  out.time = 0.0f;
  out.tfar = r.tmax;
  out.mask = 0xffffffffu;
  out.id = index;  // TraceContext::skips[index] is r's
  out.flags = 0;
}

// Field by field, through a volatile view: Embree stores each field on its
// own, and read as they are declared, u and v (primID and geomID) became one
// 8-byte load, which waits for both stores to reach the cache (a load is
// forwarded from one store only): two thirds of Accel::intersect's time on
// smoke-grid.
static Hit to_hit(const RTCRayHit& hit) {
  const volatile RTCRayHit& rh = hit;
  Hit h;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
  h.t = rh.ray.tfar;
  h.u = rh.hit.u;
  h.v = rh.hit.v;
  h.geom = rh.hit.geomID;
  h.prim = rh.hit.primID;
  h.inst = rh.hit.instID[0];
  return h;
}

namespace {

// Embree's packet of N rays and its closest-hit query, by width.
template <int N> struct Packet;
template <> struct Packet<4> {
  using RayHit = RTCRayHit4;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect4(valid, s, c, r); }
};
template <> struct Packet<8> {
  using RayHit = RTCRayHit8;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect8(valid, s, c, r); }
};
template <> struct Packet<16> {
  using RayHit = RTCRayHit16;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect16(valid, s, c, r); }
};

// Coherent rays (a camera batch: neighbouring samples of one pixel, then its
// neighbours) traced N at a time: the packet walks the BVH once for all N.
// A short last packet repeats its last ray in the lanes it masks off.
template <int N>
void intersect_packets(RTCScene top, TraceContext& ctx, std::span<const Ray> rays, std::span<Hit> hits) {
  using P = Packet<N>;
  const size_t n = std::min(rays.size(), hits.size());
  for (size_t start = 0; start < n; start += N) {
    const size_t m = std::min<size_t>(N, n - start);
    alignas(64) int valid[N];
    alignas(64) typename P::RayHit rh;
    for (size_t j = 0; j < size_t(N); ++j) {
      const Ray& r = rays[start + std::min(j, m - 1)];
      valid[j] = j < m ? -1 : 0;
      rh.ray.org_x[j] = r.o.x, rh.ray.org_y[j] = r.o.y, rh.ray.org_z[j] = r.o.z;
      rh.ray.dir_x[j] = r.d.x, rh.ray.dir_y[j] = r.d.y, rh.ray.dir_z[j] = r.d.z;
      rh.ray.tnear[j] = r.tmin, rh.ray.tfar[j] = r.tmax, rh.ray.time[j] = 0.0f;
      rh.ray.mask[j] = 0xffffffffu, rh.ray.id[j] = uint32_t(start + j), rh.ray.flags[j] = 0;
      rh.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID, rh.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
    }
    P::intersect(valid, top, &ctx.rtc, &rh);
    for (size_t j = 0; j < m; ++j) {
      Hit h;
      if (rh.hit.geomID[j] != RTC_INVALID_GEOMETRY_ID) {
        h.t = rh.ray.tfar[j], h.u = rh.hit.u[j], h.v = rh.hit.v[j];
        h.geom = rh.hit.geomID[j], h.prim = rh.hit.primID[j], h.inst = rh.hit.instID[0][j];
      }
      hits[start + j] = h;
    }
  }
}

}  // namespace

void Accel::intersect(std::span<const Ray> rays, std::span<Hit> hits, bool coherent,
                      std::span<const PrimRef> skips, bool surface) const {
  TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.surface = surface;
  ctx.rtc.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  if (!skips.empty()) ctx.skips = skips.data();
  if (coherent) {
    switch (impl_->packet_width) {
      case 16: return intersect_packets<16>(impl_->top, ctx, rays, hits);
      case 8: return intersect_packets<8>(impl_->top, ctx, rays, hits);
      case 4: return intersect_packets<4>(impl_->top, ctx, rays, hits);
      default: break;
    }
  }
  size_t n = std::min(rays.size(), hits.size());
  for (size_t i = 0; i < n; ++i) {
    RTCRayHit rh;
    fill_ray(rays[i], uint32_t(i), rh.ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->top, &ctx.rtc, &rh);
    hits[i] = to_hit(rh);
  }
}

void Accel::occluded(std::span<const Ray> rays, std::span<uint8_t> blocked, std::span<const PrimRef> skips) const {
  TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  constexpr size_t kChunk = 64;
  RTCRay buf[kChunk];
  size_t n = std::min(rays.size(), blocked.size());
  for (size_t start = 0; start < n; start += kChunk) {
    size_t m = std::min(kChunk, n - start);
    if (!skips.empty()) ctx.skips = skips.data() + start;
    for (size_t j = 0; j < m; ++j) fill_ray(rays[start + j], uint32_t(j), buf[j]);
    rtcOccluded1M(impl_->top, &ctx.rtc, buf, unsigned(m), sizeof(RTCRay));
    for (size_t j = 0; j < m; ++j) blocked[start + j] = buf[j].tfar < 0.0f ? 1 : 0;
  }
}

Accel::PassingTrace Accel::intersect_passing(const Ray& ray, const PrimRef& skip, bool surface) const {
  PassingLog log{this, &impl_->shape_passes, Hit{}, 0};
  TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.surface = surface;
  ctx.rtc.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  ctx.rtc.filter = record_passing;
  ctx.skips = &skip;
  ctx.passing = &log;
  RTCRayHit rh;
  fill_ray(ray, 0, rh.ray);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->top, &ctx.rtc, &rh);
  PassingTrace out;
  out.stop = to_hit(rh);
  out.first_pass = log.first;
  out.passes = log.count;
  return out;
}

Hit Accel::intersect1(const Ray& ray, const PrimRef& skip, bool surface) const {
  Hit h;
  intersect(std::span<const Ray>(&ray, 1), std::span<Hit>(&h, 1), false, std::span<const PrimRef>(&skip, 1), surface);
  return h;
}

bool Accel::occluded1(const Ray& ray, const PrimRef& skip) const {
  uint8_t b = 0;
  occluded(std::span<const Ray>(&ray, 1), std::span<uint8_t>(&b, 1), std::span<const PrimRef>(&skip, 1));
  return b != 0;
}

vec2 Accel::quadric_uv(const Ray& ray, const Hit& hit) const {
  const QuadricGeom* g = hit.geom < impl_->top_quadric.size() ? impl_->top_quadric[hit.geom] : nullptr;
  if (!g) return {hit.u, hit.v};
  // The closest root past tmin is the one the trace accepted (it lay below
  // the ray's tfar then), and it is found from the same doubles.
  QuadricHit qh;
  if (!quadric_hit(*g, glm::dvec3(ray.o), glm::dvec3(ray.d), double(ray.tmin), kInfinity, &qh, true)) return {0.0f, 0.0f};
  return {qh.u, qh.v};
}

const vec3* Accel::passing_unit_normals(int shape) const {
  if (shape < 0 || size_t(shape) >= impl_->passing_normals.size() || impl_->passing_normals[size_t(shape)].empty())
    return nullptr;
  return impl_->passing_normals[size_t(shape)].data();
}

int Accel::shape_index(const Hit& hit) const {
  if (hit.geom == kInvalidId) return -1;
  if (hit.inst == kInvalidId) return hit.geom < impl_->top_shape.size() ? impl_->top_shape[hit.geom] : -1;
  int i = instance_index(hit);
  if (i < 0) return -1;
  const std::vector<int>& table = impl_->proto_shape[size_t(impl_->instance_prototype[size_t(i)])];
  return hit.geom < table.size() ? table[hit.geom] : -1;
}

size_t Accel::top_geometry_count() const { return impl_->top_shape.size(); }

int Accel::instance_index(const Hit& hit) const {
  if (hit.geom == kInvalidId || hit.inst == kInvalidId || hit.inst >= impl_->top_instance.size()) return -1;
  return impl_->top_instance[hit.inst];
}

const glm::dmat4& Accel::render_from_instance(int i) const { return impl_->render_from_instance[size_t(i)]; }
const glm::dmat4& Accel::instance_from_render(int i) const { return impl_->instance_from_render[size_t(i)]; }

Bounds3 Accel::bounds() const {
  RTCBounds b;
  rtcGetSceneBounds(impl_->top, &b);
  Bounds3 r;
  if (b.lower_x > b.upper_x || b.lower_y > b.upper_y || b.lower_z > b.upper_z) return r;
  r.min = vec3(b.lower_x, b.lower_y, b.lower_z);
  r.max = vec3(b.upper_x, b.upper_y, b.upper_z);
  return r;
}

size_t Accel::memory_bytes() const {
  int64_t embree = std::max<int64_t>(impl_->embree_bytes.load(), 0);
  size_t own = impl_->quadrics.size() * sizeof(QuadricGeom) + impl_->filter_geoms.size() * sizeof(FilterGeom) +
               (impl_->top_shape.size() + impl_->top_instance.size()) * sizeof(int) +
               (impl_->render_from_instance.size() + impl_->instance_from_render.size()) * sizeof(glm::dmat4);
  for (const auto& t : impl_->proto_shape) own += t.size() * sizeof(int);
  for (const auto& n : impl_->passing_normals) own += n.size() * sizeof(vec3);
  return size_t(embree) + own + impl_->curve_bytes;
}

}  // namespace theia
