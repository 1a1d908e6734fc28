// A layered sample's MIS pdf, deferred to the emitter its ray finds
// (EngineOptions::defer_layered_pdf, PathState::prev_pdf == kDeferredPdf),
// weighs emission exactly as the pdf computed at the vertex does: the two
// renders agree but for the rounding of f / pdf.  A wrong or stale deferred
// pdf (another path's table entry, the walk's proportional pdf) moves the
// emitters' MIS weights and so the pixels that see a light through a coat.
#include "render_helpers.h"
#include "scene/accel.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

// Rough-coated spheres (diffuse and conductor bases, one with a scattering
// layer) on a diffuse floor, in a coloured sky (escaped rays) beside a small
// bright sphere light (emitter hits): both kinds of emitter are found by rays
// that layered BSDFs sampled, and both are sampled by NEE, so MIS weighs them.
std::string layered_scene() {
  return R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [24]
    Integrator "volpath" "integer maxdepth" [8]
    LookAt 0 2.5 -6  0 0.6 0  0 1 0
    Camera "perspective" "float fov" [40]
    WorldBegin
    LightSource "infinite" "rgb L" [0.4 0.5 0.8]
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [60 50 40]
      Translate 2 3 -1
      Shape "sphere" "float radius" [0.25]
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-6 0 -6  6 0 -6  6 0 6  -6 0 6] "integer indices" [0 1 2 0 2 3]
    AttributeBegin
      Material "coateddiffuse" "rgb reflectance" [0.7 0.3 0.1] "float roughness" [0.15]
      Translate -1.2 0.9 0
      Shape "sphere" "float radius" [0.9]
    AttributeEnd
    AttributeBegin
      Material "coatedconductor" "float interface.roughness" [0.05] "float conductor.roughness" [0.3]
        "rgb albedo" [0.6 0.6 0.6] "float thickness" [0.05]
      Translate 1.1 0.8 0.5
      Shape "sphere" "float radius" [0.8]
    AttributeEnd
  )";
}

ImageBuffer render(const RenderableScene& rs, bool defer) {
  EngineOptions opt;
  opt.max_depth = 8;
  opt.defer_layered_pdf = defer;
  Film film(rs.scene.film.width, rs.scene.film.height);
  WavefrontEngine(rs, film, opt).render(0, 16);
  return resolve_film(film);
}

}  // namespace

TEST(LayeredMis, DeferredPdfWeighsEmittersAsTheEagerPdf) {
  Scene scene = load_test_scene(layered_scene());
  RenderableScene rs(scene);
  const ImageBuffer eager = render(rs, false), deferred = render(rs, true);
  // Both render something: the sky, the light's reflections on the coats.
  double sum = 0.0;
  for (float v : eager.data) sum += v;
  ASSERT_GT(sum, 0.0);
  EXPECT_LT(max_relative_difference(eager, deferred), 1e-4);
}
