// theia_bench: what the wavefront engine costs over raw Embree, and what
// sorting buys.  Renders the Cornell box and a generated scene of over a
// million triangles with sorting on and off, then re-traces the very same rays
// alone (no shading, no queues) to get the raw Embree rate.  The ratio of the
// two is the engine's overhead.  Figures in the README come from this program.
//
//   theia_bench [--spp N] [--threads N] [--json FILE]
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

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>

using namespace theia;

namespace {

// A field of bumpy spheres (each a displaced UV sphere) on a floor under an
// area light: over a million triangles, and plenty of interreflection.
Scene make_million_triangle_scene() {
  Scene s = parse_scene_string(R"(
    Film "rgb" "integer xresolution" [160] "integer yresolution" [120]
    Integrator "path" "integer maxdepth" [8]
    LookAt 0 6 -14  0 0.5 0  0 1 0
    Camera "perspective" "float fov" [40]
    WorldBegin
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [20 20 20]
      Shape "trianglemesh" "point3 P" [-2 8 -2  2 8 -2  2 8 2  -2 8 2] "integer indices" [0 2 1 0 3 2]
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.6 0.6 0.6]
    Shape "trianglemesh" "point3 P" [-20 0 -20  20 0 -20  20 0 20  -20 0 20] "integer indices" [0 1 2 0 2 3]
  )",
                               "<bench>");
  const int kSpheres = 4, kRings = 256, kSegments = 256;  // 16 spheres x 2 x 256 x 256 ~= 2.1M triangles
  Material m;
  m.name = "bumpy";
  Texture t;
  t.value = RGB(0.7f, 0.5f, 0.3f);
  s.textures.push_back(t);
  m.reflectance = int(s.textures.size()) - 1;
  s.materials.push_back(m);
  for (int i = 0; i < kSpheres; ++i)
    for (int j = 0; j < kSpheres; ++j) {
      TriangleMesh mesh;
      vec3 c(-4.5f + 3.0f * float(i), 1.0f, -4.5f + 3.0f * float(j));
      for (int r = 0; r <= kRings; ++r)
        for (int q = 0; q <= kSegments; ++q) {
          float theta = kPi * float(r) / kRings, phi = 2.0f * kPi * float(q) / kSegments;
          vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
          float bump = 1.0f + 0.08f * std::sin(9.0f * phi + float(i)) * std::sin(7.0f * theta + float(j));
          mesh.p.push_back(c + n * bump);
        }
      for (int r = 0; r < kRings; ++r)
        for (int q = 0; q < kSegments; ++q) {
          uint32_t a = uint32_t(r * (kSegments + 1) + q), b = a + 1, d = a + uint32_t(kSegments + 1), e = d + 1;
          mesh.indices.insert(mesh.indices.end(), {a, d, b, b, d, e});
        }
      s.meshes.push_back(std::move(mesh));
      Shape shape;
      shape.mesh = int(s.meshes.size()) - 1;
      shape.material = int(s.materials.size()) - 1;
      s.shapes.push_back(shape);
      s.top_level_shapes.push_back(int(s.shapes.size()) - 1);
    }
  return s;
}

struct Measurement {
  double engine_mrays = 0, trace_phase_mrays = 0, raw_mrays = 0, render_seconds = 0;
  uint64_t rays = 0;
};

Measurement measure(const Scene& scene, int spp, bool sort) {
  RenderableScene rs(scene);
  const Accel& accel = rs.accel;
  Film film(scene.film.width, scene.film.height);
  std::vector<Ray> rays, shadow_rays;
  EngineOptions opt;
  opt.max_depth = scene.settings.max_depth;
  opt.sort = sort;
  opt.capture_rays = &rays;
  opt.capture_shadow_rays = &shadow_rays;
  WavefrontEngine engine(rs, film, opt);
  engine.render(0, uint32_t(spp));
  const EngineStats& st = engine.stats();
  Measurement m;
  m.rays = st.total_rays();
  m.render_seconds = st.render_seconds;
  m.engine_mrays = double(m.rays) / st.render_seconds * 1e-6;
  m.trace_phase_mrays = double(m.rays) / (st.phases[Phase::Trace] + st.phases[Phase::TraceShadow]) * 1e-6;

  // The same rays, in the same (sorted or queue) order, traced alone.
  std::vector<Hit> hits(rays.size());
  std::vector<uint8_t> blocked(shadow_rays.size());
  auto t0 = std::chrono::steady_clock::now();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
    accel.intersect(std::span<const Ray>(rays.data() + r.begin(), r.size()),
                    std::span<Hit>(hits.data() + r.begin(), r.size()), false);
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, shadow_rays.size(), 256),
                    [&](const tbb::blocked_range<size_t>& r) {
                      accel.occluded(std::span<const Ray>(shadow_rays.data() + r.begin(), r.size()),
                                     std::span<uint8_t>(blocked.data() + r.begin(), r.size()));
                    });
  m.raw_mrays = double(rays.size() + shadow_rays.size()) / seconds_since(t0) * 1e-6;
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  int spp = 16, threads = 0;
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--spp") && i + 1 < argc) spp = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) threads = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
    else {
      std::fprintf(stderr, "usage: theia_bench [--spp N] [--threads N] [--json FILE]\n");
      return 2;
    }
  }
  std::unique_ptr<tbb::global_control> tc;
  if (threads > 0) tc = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  set_verbosity(Verbosity::Quiet);

  Scene cornell = load_scene(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
  load_images(cornell);
  Scene million = make_million_triangle_scene();
  size_t tris = 0;
  for (const TriangleMesh& m : million.meshes) tris += m.triangle_count();

  nlohmann::json out;
  std::printf("%-22s %-5s %10s %10s %12s %10s %9s\n", "scene", "sort", "rays(M)", "engine", "trace-phase", "raw",
              "overhead");
  for (auto [name, scene] : {std::pair<const char*, const Scene*>{"cornell-box", &cornell},
                             std::pair<const char*, const Scene*>{"bumpy-spheres-2.1M", &million}}) {
    for (bool sort : {true, false}) {
      Measurement m = measure(*scene, spp, sort);
      std::printf("%-22s %-5s %10.2f %9.2fM %11.2fM %9.2fM %8.2fx\n", name, sort ? "on" : "off", double(m.rays) * 1e-6,
                  m.engine_mrays, m.trace_phase_mrays, m.raw_mrays, m.raw_mrays / m.engine_mrays);
      out[name][sort ? "sort_on" : "sort_off"] = {{"rays", m.rays},
                                                  {"render_seconds", m.render_seconds},
                                                  {"engine_mrays_per_s", m.engine_mrays},
                                                  {"trace_phase_mrays_per_s", m.trace_phase_mrays},
                                                  {"raw_embree_mrays_per_s", m.raw_mrays}};
    }
  }
  std::printf("(spp %d; %zu triangles in the generated scene; rates in Mrays/s; overhead = raw / engine)\n", spp, tris);
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(2) << "\n";
  return 0;
}
