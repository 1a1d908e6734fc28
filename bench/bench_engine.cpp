// theia_bench: what the wavefront engine costs over raw Embree, and what
// sorting buys.  Renders the Cornell box and a generated scene of over a
// million triangles with sorting on and off, then re-traces the very same rays
// alone (no shading, no queues) to get the raw Embree rate.  The ratio of the
// two is the engine's overhead.  --large renders a production-sized frame
// instead: 1920x1080 over 10.5M instanced triangles.  Figures in the README
// and bench/README.md come from this program.
//
//   theia_bench [--large] [--spp N] [--threads N[,N...]] [--runs K] [--json FILE]
//               [--scene PREFIX] [--phases] [--engine-only] [--max-paths N] [--batch-size N]
#include "app/render.h"
#include "cachepoints/light_sampler.h"
#include "core/log.h"
#include "core/stats.h"
#include "scene/accel.h"
#include "scene/camera.h"
#include "scene/filter.h"
#include "scene/lights.h"
#include "scene/parser.h"
#include "scene/texture.h"
#include "wavefront/engine.h"

#include <fmt/core.h>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

using namespace theia;

namespace {

// A bumpy sphere (a displaced UV sphere) of 2 x rings x segments triangles
// around c; (i, j) vary the bumps from one sphere to the next.
TriangleMesh bumpy_sphere(vec3 c, int rings, int segments, int i, int j) {
  TriangleMesh mesh;
  for (int r = 0; r <= rings; ++r)
    for (int q = 0; q <= segments; ++q) {
      float theta = kPi * float(r) / float(rings), phi = 2.0f * kPi * float(q) / float(segments);
      vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
      float bump = 1.0f + 0.08f * std::sin(9.0f * phi + float(i)) * std::sin(7.0f * theta + float(j));
      mesh.p.push_back(c + n * bump);
    }
  for (int r = 0; r < rings; ++r)
    for (int q = 0; q < segments; ++q) {
      uint32_t a = uint32_t(r * (segments + 1) + q), b = a + 1, d = a + uint32_t(segments + 1), e = d + 1;
      mesh.indices.insert(mesh.indices.end(), {a, d, b, b, d, e});
    }
  return mesh;
}

// A bench scene's header (film, integrator, camera), its area light (a quad
// given as pbrt-v4 trianglemesh parameters) and the floor it lights.
Scene light_and_floor(const std::string& header, const std::string& light_quad) {
  return parse_scene_string(header + R"(
    WorldBegin
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [20 20 20]
      Shape "trianglemesh" )" + light_quad + R"(
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.6 0.6 0.6]
    Shape "trianglemesh" "point3 P" [-20 0 -20  20 0 -20  20 0 20  -20 0 20] "integer indices" [0 1 2 0 2 3]
  )",
                            "<bench>");
}

// The material every bumpy sphere wears; returns its index.
int add_bumpy_material(Scene& s) {
  Material m;
  m.name = "bumpy";
  Texture t;
  t.value = RGB(0.7f, 0.5f, 0.3f);
  s.textures.push_back(t);
  m.reflectance = int(s.textures.size()) - 1;
  s.materials.push_back(m);
  return int(s.materials.size()) - 1;
}

int add_mesh_shape(Scene& s, TriangleMesh mesh, int material) {
  s.meshes.push_back(std::move(mesh));
  Shape shape;
  shape.mesh = int(s.meshes.size()) - 1;
  shape.material = material;
  s.shapes.push_back(shape);
  return int(s.shapes.size()) - 1;
}

// A field of 16 bumpy spheres on a floor under an area light: over a million
// triangles.
Scene make_million_triangle_scene() {
  // This light's winding makes it face up, away from the scene, so the image
  // is almost black and paths end at their first bounce; kept as it is, since
  // the README's figures were measured on it (--large's light faces down).
  Scene s = light_and_floor(R"(
    Film "rgb" "integer xresolution" [160] "integer yresolution" [120]
    Integrator "path" "integer maxdepth" [8]
    LookAt 0 6 -14  0 0.5 0  0 1 0
    Camera "perspective" "float fov" [40]
  )",
                            R"("point3 P" [-2 8 -2  2 8 -2  2 8 2  -2 8 2] "integer indices" [0 2 1 0 3 2])");
  const int kSpheres = 4, kRings = 256, kSegments = 256;  // 16 spheres x 2 x 256 x 256 ~= 2.1M triangles
  int material = add_bumpy_material(s);
  for (int i = 0; i < kSpheres; ++i)
    for (int j = 0; j < kSpheres; ++j) {
      vec3 c(-4.5f + 3.0f * float(i), 1.0f, -4.5f + 3.0f * float(j));
      s.top_level_shapes.push_back(add_mesh_shape(s, bumpy_sphere(c, kRings, kSegments, i, j), material));
    }
  return s;
}

// A production-sized frame: 1920x1080 over a 10 x 8 grid of instanced bumpy
// spheres, 80 x 131,072 = 10.5M triangles.  Instances share one prototype
// (ObjectBegin/ObjectInstance), each turned about its vertical axis so the
// bumps differ; the camera looks across the grid, so most pixels see
// geometry and a sphere's triangles are smaller than a pixel, as in
// production scenes whose BVH does not fit in cache.
Scene make_ten_million_triangle_scene() {
  Scene s = light_and_floor(R"(
    Film "rgb" "integer xresolution" [1920] "integer yresolution" [1080]
    Integrator "path" "integer maxdepth" [8]
    LookAt 0 7 -17  0 0 1  0 1 0
    Camera "perspective" "float fov" [40]
  )",
                            R"("point3 P" [-4 10 -4  4 10 -4  4 10 4  -4 10 4] "integer indices" [0 1 2 0 2 3])");
  const int kColumns = 10, kRows = 8, kRings = 256, kSegments = 256;
  int material = add_bumpy_material(s);
  s.prototypes.push_back({"bumpy-sphere", {add_mesh_shape(s, bumpy_sphere(vec3(0.0f), kRings, kSegments, 0, 0), material)}});
  for (int i = 0; i < kColumns; ++i)
    for (int j = 0; j < kRows; ++j) {
      vec3 c(-11.25f + 2.5f * float(i), 1.0f, -7.0f + 2.5f * float(j));
      mat4 m = glm::rotate(glm::translate(mat4(1.0f), c), 0.7f * float(i * kRows + j), vec3(0, 1, 0));
      s.instances.push_back({0, Transform(m)});
    }
  return s;
}

// Triangles as traced: an instance counts its prototype's triangles again.
size_t traced_triangles(const Scene& s) {
  auto shape_tris = [&](int shape) {
    const Shape& sh = s.shapes[size_t(shape)];
    return sh.kind == ShapeKind::TriangleMesh ? s.meshes[size_t(sh.mesh)].triangle_count() : size_t(0);
  };
  size_t n = 0;
  for (int shape : s.top_level_shapes) n += shape_tris(shape);
  for (const Instance& inst : s.instances)
    for (int shape : s.prototypes[size_t(inst.prototype)].shapes) n += shape_tris(shape);
  return n;
}

struct Measurement {
  double engine_mrays = 0, trace_phase_mrays = 0, raw_mrays = 0, render_seconds = 0, render_cpu_seconds = 0;
  double raw_cpu_seconds = 0;  // the raw pass's process CPU seconds
  uint64_t rays = 0;
  PhaseTimes<Phase, size_t(Phase::Count)> phases;
  double wall_overhead() const { return raw_mrays > 0 ? raw_mrays / engine_mrays : 0.0; }
  // On a shared machine the steadier figure: other processes' load slows
  // both passes' wall clocks unevenly, their CPU seconds far less.
  double cpu_overhead() const { return raw_cpu_seconds > 0 ? render_cpu_seconds / raw_cpu_seconds : 0.0; }
};

// engine_only: the timed render alone, for profiling it (no capturing
// render, no raw pass: raw_mrays stays 0).
Measurement measure(const RenderableScene& rs, int spp, bool sort, bool engine_only, size_t max_paths,
                    size_t batch_size) {
  const Scene& scene = rs.scene;
  const Accel& accel = rs.accel;
  EngineOptions opt;
  opt.max_depth = scene.settings.max_depth;
  opt.sort = sort;
  opt.max_paths = max_paths;
  opt.batch_size = batch_size;
  Measurement m;
  {
    Film film(scene.film.width, scene.film.height);
    WavefrontEngine engine(rs, film, opt);
    double cpu0 = process_cpu_seconds();
    engine.render(0, uint32_t(spp));
    double render_cpu = process_cpu_seconds() - cpu0;
    const EngineStats& st = engine.stats();
    m.rays = st.total_rays();
    m.render_seconds = st.render_seconds;
    m.render_cpu_seconds = render_cpu;
    m.engine_mrays = double(m.rays) / st.render_seconds * 1e-6;
    m.trace_phase_mrays = double(m.rays) / (st.phases[Phase::Trace] + st.phases[Phase::TraceShadow]) * 1e-6;
    m.phases = st.phases;
  }
  if (engine_only) return m;

  // The same rays, in the same (sorted or queue) order, traced alone.  They
  // are captured by a second, untimed render (the engine is deterministic):
  // appending every batch to one growing array is serial work and page faults
  // that the timed render must not carry.
  // Camera rays are captured apart and traced as the engine traces them, in
  // packets (Accel::intersect's `coherent`): what the engine gains there is
  // Embree's, not the engine's.
  std::vector<Ray> camera_rays, rays, shadow_rays;
  {
    Film film(scene.film.width, scene.film.height);
    opt.capture_camera_rays = &camera_rays;
    opt.capture_rays = &rays;
    opt.capture_shadow_rays = &shadow_rays;
    WavefrontEngine engine(rs, film, opt);
    engine.render(0, uint32_t(spp));
    const size_t captured = camera_rays.size() + rays.size() + shadow_rays.size();
    if (captured != m.rays) {
      std::fprintf(stderr, "theia_bench: the capturing render traced %zu rays, the timed one %llu\n", captured,
                   static_cast<unsigned long long>(m.rays));
      std::exit(1);
    }
  }
  std::vector<Hit> hits(std::max(camera_rays.size(), rays.size()));
  std::vector<uint8_t> blocked(shadow_rays.size());
  auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_seconds();
  for (const std::vector<Ray>* traced : {&camera_rays, &rays}) {
    const bool coherent = traced == &camera_rays;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, traced->size(), 256), [&](const tbb::blocked_range<size_t>& r) {
      accel.intersect(std::span<const Ray>(traced->data() + r.begin(), r.size()),
                      std::span<Hit>(hits.data() + r.begin(), r.size()), coherent);
    });
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, shadow_rays.size(), 256),
                    [&](const tbb::blocked_range<size_t>& r) {
                      accel.occluded(std::span<const Ray>(shadow_rays.data() + r.begin(), r.size()),
                                     std::span<uint8_t>(blocked.data() + r.begin(), r.size()));
                    });
  m.raw_mrays = double(camera_rays.size() + rays.size() + shadow_rays.size()) / seconds_since(t0) * 1e-6;
  m.raw_cpu_seconds = process_cpu_seconds() - cpu0;
  return m;
}

struct BenchOptions {
  int spp = 0;                 // 0: 16, or 2 with --large
  std::vector<int> threads{0}; // each count in turn; 0: every core
  int runs = 1;                // sort on, off, on, off, ...: interleaved so load falls on both alike
  bool large = false;          // the 10.5M-triangle 1080p scene instead of the two small ones
  std::string json_path;
  std::string scene;           // only the scenes whose name starts with this
  bool phases = false;         // each render's phase seconds (EngineStats::phases) after its row
  bool engine_only = false;    // the timed render alone (for a profiler): no raw Embree pass
  size_t max_paths = 0, batch_size = 0;  // 0: the engine's own sizes (engine_sizes)
};

bool parse_threads(const char* list, std::vector<int>& out) {
  out.clear();
  for (const char* c = list; *c;) {
    char* end = nullptr;
    long n = std::strtol(c, &end, 10);
    if (end == c || n < 0) return false;
    out.push_back(int(n));
    c = *end == ',' ? end + 1 : end;
    if (*end && *end != ',') return false;
  }
  return !out.empty();
}

bool parse_size(const char* text, size_t& out) {
  char* end = nullptr;
  const long long n = std::strtoll(text, &end, 10);
  if (end == text || *end || n < 0) return false;
  out = size_t(n);
  return true;
}

bool parse_args(int argc, char** argv, BenchOptions& o) {
  for (int i = 1; i < argc; ++i) {
    bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--spp") && has_value) o.spp = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--threads") && has_value) { if (!parse_threads(argv[++i], o.threads)) return false; }
    else if (!std::strcmp(argv[i], "--runs") && has_value) o.runs = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--json") && has_value) o.json_path = argv[++i];
    else if (!std::strcmp(argv[i], "--scene") && has_value) o.scene = argv[++i];
    else if (!std::strcmp(argv[i], "--large")) o.large = true;
    else if (!std::strcmp(argv[i], "--phases")) o.phases = true;
    else if (!std::strcmp(argv[i], "--engine-only")) o.engine_only = true;
    else if (!std::strcmp(argv[i], "--max-paths") && has_value) { if (!parse_size(argv[++i], o.max_paths)) return false; }
    else if (!std::strcmp(argv[i], "--batch-size") && has_value) { if (!parse_size(argv[++i], o.batch_size)) return false; }
    else return false;
  }
  if (o.spp == 0) o.spp = o.large ? 2 : 16;
  return o.spp > 0 && o.runs > 0;
}

struct Row {
  std::string scene;
  int threads = 0, run = 0;
  bool sort = true;
  Measurement m;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Medians over runs of the render's wall and CPU seconds (sort on against
// off, and every thread count against the first) and of the overheads.
void print_summary(const std::vector<Row>& rows, const std::vector<std::string>& scenes, const std::vector<int>& threads) {
  // `figure`: a field of Measurement or one of its figures (wall_overhead).
  auto med = [&](const std::string& scene, int t, bool sort, auto figure) {
    std::vector<double> v;
    for (const Row& r : rows)
      if (r.scene == scene && r.threads == t && r.sort == sort) v.push_back(std::invoke(figure, r.m));
    return median(v);
  };
  const auto wall = &Measurement::render_seconds, cpu = &Measurement::render_cpu_seconds;
  std::printf("\nmedians over runs (render only):\n%-22s %7s %12s %12s %8s %12s %12s %8s\n", "scene", "threads",
              "on wall-s", "off wall-s", "off/on", "on cpu-s", "off cpu-s", "off/on");
  for (const std::string& scene : scenes)
    for (int t : threads) {
      double on = med(scene, t, true, wall), off = med(scene, t, false, wall);
      double on_cpu = med(scene, t, true, cpu), off_cpu = med(scene, t, false, cpu);
      std::printf("%-22s %7d %12.2f %12.2f %7.3fx %12.2f %12.2f %7.3fx\n", scene.c_str(), t, on, off, off / on, on_cpu,
                  off_cpu, off_cpu / on_cpu);
    }
  if (rows.front().m.raw_mrays > 0) {
    std::printf("\nmedian overhead over runs (wall, CPU):\n%-22s %7s %18s %18s\n", "scene", "threads", "sort on",
                "sort off");
    for (const std::string& scene : scenes)
      for (int t : threads)
        std::printf("%-22s %7d %8.2fx %8.2fx %8.2fx %8.2fx\n", scene.c_str(), t,
                    med(scene, t, true, &Measurement::wall_overhead), med(scene, t, true, &Measurement::cpu_overhead),
                    med(scene, t, false, &Measurement::wall_overhead), med(scene, t, false, &Measurement::cpu_overhead));
  }
  if (threads.size() < 2) return;
  std::printf("\nthread scaling (median render wall seconds at %d threads / at N):\n", threads[0]);
  for (const std::string& scene : scenes)
    for (bool sort : {true, false})
      for (size_t k = 1; k < threads.size(); ++k)
        std::printf("%-22s sort %-3s %d -> %d threads: %.2fx\n", scene.c_str(), sort ? "on" : "off", threads[0],
                    threads[k], med(scene, threads[0], sort, wall) / med(scene, threads[k], sort, wall));
}

void print_phases(const Measurement& m) {
  std::printf("  phases (s):");
  for (size_t p = 0; p < size_t(Phase::Count); ++p) std::printf(" %s %.3f", kPhaseNames[p], m.phases.seconds[p]);
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
  BenchOptions o;
  if (!parse_args(argc, argv, o)) {
    std::fprintf(stderr,
                 "usage: theia_bench [--large] [--spp N] [--threads N[,N...]] [--runs K] [--json FILE]\n"
                 "                   [--scene PREFIX] [--phases] [--engine-only] [--max-paths N] [--batch-size N]\n");
    return 2;
  }
  set_verbosity(Verbosity::Quiet);

  std::vector<std::pair<std::string, Scene>> scenes;
  if (o.large) {
    scenes.emplace_back("", make_ten_million_triangle_scene());
  } else {
    // Read from the source tree only when asked for: one clear error if
    // the tree has moved, and none for --scene bumpy.
    if (o.scene.empty() || std::string("cornell-box").starts_with(o.scene)) {
      try {
        Scene cornell = load_scene(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
        load_images(cornell);
        scenes.emplace_back("cornell-box", std::move(cornell));
      } catch (const Error& e) {
        std::fprintf(stderr, "theia_bench: %s\n", e.what());
        return 1;
      }
    }
    if (o.scene.empty() || std::string("bumpy-spheres").starts_with(o.scene))
      scenes.emplace_back("", make_million_triangle_scene());
  }
  std::vector<std::string> names;
  for (auto& [name, scene] : scenes) {
    if (name.empty()) name = fmt::format("bumpy-spheres-{:.1f}M", double(traced_triangles(scene)) * 1e-6);
    names.push_back(name);
  }

  std::vector<Row> rows;
  nlohmann::json out = nlohmann::json::array();
  std::printf("%-22s %-5s %7s %10s %10s %12s %10s %9s %9s %9s %9s\n", "scene", "sort", "threads", "rays(M)", "engine",
              "trace-phase", "raw", "overhead", "cpu-ovh", "wall-s", "cpu-s");
  for (int& threads : o.threads) {  // 0 becomes the count in effect
    std::unique_ptr<tbb::global_control> tc;
    if (threads > 0) tc = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
    threads = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    for (const auto& [name, scene] : scenes) {
      // Built once: a profile of the renders (--engine-only) then holds one
      // BVH build, which perf record -D can leave out.
      const RenderableScene rs(scene);
      for (int run = 0; run < o.runs; ++run)
        for (bool sort : {true, false}) {
          Measurement m = measure(rs, o.spp, sort, o.engine_only, o.max_paths, o.batch_size);
          std::printf("%-22s %-5s %7d %10.2f %9.2fM %11.2fM %9.2fM %8.2fx %8.2fx %9.2f %9.2f\n", name.c_str(),
                      sort ? "on" : "off", threads, double(m.rays) * 1e-6, m.engine_mrays, m.trace_phase_mrays,
                      m.raw_mrays, m.wall_overhead(), m.cpu_overhead(), m.render_seconds,
                      m.render_cpu_seconds);
          if (o.phases) print_phases(m);
          std::fflush(stdout);
          rows.push_back({name, threads, run, sort, m});
          out.push_back({{"scene", name},
                         {"triangles", traced_triangles(scene)},
                         {"width", scene.film.width},
                         {"height", scene.film.height},
                         {"spp", o.spp},
                         {"threads", threads},
                         {"run", run},
                         {"sort", sort},
                         {"rays", m.rays},
                         {"render_seconds", m.render_seconds},
                         {"render_cpu_seconds", m.render_cpu_seconds},
                         {"engine_mrays_per_s", m.engine_mrays},
                         {"trace_phase_mrays_per_s", m.trace_phase_mrays},
                         {"raw_embree_mrays_per_s", m.raw_mrays},
                         {"raw_embree_cpu_seconds", m.raw_cpu_seconds}});
        }
    }
  }
  std::printf("(spp %d; rates in Mrays/s; overhead = raw / engine; cpu-ovh = the render's CPU seconds / the raw "
              "pass's)\n",
              o.spp);
  if (o.runs > 1 || o.threads.size() > 1) print_summary(rows, names, o.threads);
  if (!o.json_path.empty()) std::ofstream(o.json_path) << out.dump(2) << "\n";
  return 0;
}
