#include "core/log.h"
#include "core/color.h"
#include "scene/parser.h"
#include "scene/spectrum.h"
#include "tests/test_util.h"
#include "tests/unit/allocation_count.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sys/stat.h>

using namespace theia;
using theia::test::TempDir;
namespace fs = std::filesystem;

namespace {

// Colours in a scene file are linear sRGB; the parser stores them in the working space.
void expect_scene_color(const RGB& stored, const RGB& srgb) {
  RGB want = srgb_to_working(srgb);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(stored[c], want[c], 1e-5f * std::max(1.0f, std::abs(want[c]))) << c;
  EXPECT_NEAR(glm::length(working_to_srgb(stored) - srgb), 0.0f, 1e-5f * std::max(1.0f, glm::length(srgb)));
}


Scene parse(const std::string& text) { return parse_scene_string(text, "test.pbrt"); }

std::string error_of(const std::string& text, const std::string& base_dir = ".") {
  try {
    parse_scene_string(text, "test.pbrt", base_dir);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// Warnings a parse adds (the counter is global).
int warnings_of(const std::string& text) {
  int before = warning_count();
  parse(text);
  return warning_count() - before;
}

void expect_mat_near(const mat4& a, const mat4& b, float eps = 1e-5f) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_NEAR(a[c][r], b[c][r], eps) << "column " << c << " row " << r;
}

const char* kTri = R"(Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "normal N" [0 0 1 0 0 1 0 0 1] )";

}  // namespace

// ---------------------------------------------------------------- lexing and options

TEST(Parser, LexesCommentsStringsAndCNumbers) {
  Scene s = parse(R"(# a comment "with a string"
Film "rgb" "integer xresolution" [ +64 ] "integer yresolution" 32 # trailing
  "string filename" "out\"put\\.exr"
Camera "perspective" "float fov" [ 3e1 ] "float lensradius" .25 "float focaldistance" 5e-1
WorldBegin
Translate -.5 1e-3 +3
Shape "sphere" "float radius" 2.)");
  EXPECT_EQ(s.film.width, 64);
  EXPECT_EQ(s.film.height, 32);
  EXPECT_EQ(s.film.filename, "out\"put\\.exr");
  EXPECT_FLOAT_EQ(s.camera.fov, 30.0f);
  EXPECT_FLOAT_EQ(s.camera.lens_radius, 0.25f);
  EXPECT_FLOAT_EQ(s.camera.focal_distance, 0.5f);  // a negative one is an error (ParserHostile)
  ASSERT_EQ(s.shapes.size(), 1u);
  EXPECT_EQ(s.shapes[0].kind, ShapeKind::Sphere);
  EXPECT_FLOAT_EQ(s.shapes[0].sphere.radius, 2.0f);
  EXPECT_EQ(vec3(s.shapes[0].render_from_object.m[3]), vec3(-0.5f, 1e-3f, 3.0f));
  EXPECT_EQ(s.path, "test.pbrt");
}

TEST(Parser, OptionsBlockDirectives) {
  int before = warning_count();
  Scene s = parse(R"(Sampler "zsobol" "integer pixelsamples" 128
Integrator "volpath" "integer maxdepth" [ 7 ]
Accelerator "bvh" "integer maxnodeprims" 4
PixelFilter "triangle"
Camera "perspective" "float screenwindow" [ -1 1 -0.5 0.5 ]
ColorSpace "srgb"
Option "bool disablepixeljitter" true
WorldBegin)");
  EXPECT_EQ(warning_count() - before, 1);  // the Option
  EXPECT_EQ(s.settings.spp, 128);
  EXPECT_EQ(s.settings.max_depth, 7);
  EXPECT_EQ(s.filter.kind, FilterKind::Triangle);
  EXPECT_EQ(s.filter.radius, vec2(2.0f));
  EXPECT_TRUE(s.camera.has_screen_window);
  EXPECT_FLOAT_EQ(s.camera.screen_window[2], -0.5f);
  EXPECT_FLOAT_EQ(s.camera.screen_window[3], 0.5f);
  EXPECT_EQ(s.film.width, 1280);  // defaults stay
}

TEST(Parser, PixelFilterDefaultsAndSubstitution) {
  Scene box = parse("PixelFilter \"box\"\nWorldBegin");
  EXPECT_EQ(box.filter.kind, FilterKind::Box);
  EXPECT_EQ(box.filter.radius, vec2(0.5f));
  Scene g = parse("PixelFilter \"gaussian\" \"float sigma\" 0.25 \"float yradius\" 3\nWorldBegin");
  EXPECT_EQ(g.filter.kind, FilterKind::Gaussian);
  EXPECT_EQ(g.filter.radius, vec2(1.5f, 3.0f));
  EXPECT_FLOAT_EQ(g.filter.sigma, 0.25f);
  EXPECT_EQ(warnings_of("PixelFilter \"mitchell\" \"float B\" 0.3\nWorldBegin"), 0);
  Scene m = parse("PixelFilter \"mitchell\" \"float B\" 0.3\nWorldBegin");
  EXPECT_EQ(m.filter.kind, FilterKind::Mitchell);
  EXPECT_EQ(m.filter.radius, vec2(2.0f));
  EXPECT_FLOAT_EQ(m.filter.b, 0.3f);
  EXPECT_FLOAT_EQ(m.filter.c, 1.0f / 3.0f);
  // pbrt-v4 calls the Lanczos-windowed sinc "sinc"; "lanczos" is accepted too.
  for (const char* name : {"sinc", "lanczos"}) {
    Scene l = parse(std::string("PixelFilter \"") + name + "\" \"float tau\" 2\nWorldBegin");
    EXPECT_EQ(l.filter.kind, FilterKind::Lanczos);
    EXPECT_EQ(l.filter.radius, vec2(4.0f));
    EXPECT_FLOAT_EQ(l.filter.tau, 2.0f);
  }
  EXPECT_EQ(warnings_of("PixelFilter \"blackmanharris\" \"float B\" 0.3\nWorldBegin"), 1);
  EXPECT_EQ(parse("PixelFilter \"blackmanharris\"\nWorldBegin").filter.kind, FilterKind::Gaussian);
}

TEST(Parser, FrameAspectRatioSetsTheScreenWindow) {
  Scene s = parse("Camera \"perspective\" \"float frameaspectratio\" 2\nWorldBegin");
  ASSERT_TRUE(s.camera.has_screen_window);
  EXPECT_FLOAT_EQ(s.camera.screen_window[0], -2.0f);
  EXPECT_FLOAT_EQ(s.camera.screen_window[1], 2.0f);
  EXPECT_FLOAT_EQ(s.camera.screen_window[3], 1.0f);
}

TEST(Parser, UnsupportedFilmCameraWarn) {
  EXPECT_EQ(warnings_of("Film \"gbuffer\"\nCamera \"realistic\" \"string lensfile\" \"x.dat\"\nWorldBegin"), 2);
  EXPECT_EQ(parse("Camera \"realistic\"\nWorldBegin").camera.kind, CameraKind::Perspective);
  Scene o = parse("Camera \"orthographic\" \"float lensradius\" 0.5 \"float screenwindow\" [-2 2 -1 1]\nWorldBegin");
  EXPECT_EQ(o.camera.kind, CameraKind::Orthographic);
  EXPECT_FLOAT_EQ(o.camera.lens_radius, 0.5f);
  EXPECT_FLOAT_EQ(o.camera.screen_window[0], -2.0f);
  Scene sph = parse("Camera \"spherical\" \"string mapping\" \"equirectangular\"\nWorldBegin");
  EXPECT_EQ(sph.camera.kind, CameraKind::Spherical);
  EXPECT_EQ(sph.camera.mapping, SphericalMapping::Equirectangular);
  EXPECT_EQ(parse("Camera \"spherical\"\nWorldBegin").camera.mapping, SphericalMapping::EqualArea);
  EXPECT_EQ(warnings_of("Camera \"spherical\" \"float lensradius\" 1 \"float focaldistance\" 2\nWorldBegin"), 0);
  EXPECT_EQ(error_of("Camera \"spherical\" \"string mapping\" \"cube\"\nWorldBegin"),
            "test.pbrt:1:20: error: spherical camera mapping \"cube\", expected \"equalarea\" or \"equirectangular\"");
}

TEST(Parser, UnusedParametersWarnOnceEach) {
  EXPECT_EQ(warnings_of("WorldBegin\nShape \"sphere\" \"float radius\" 2 \"float foo\" 1 \"rgb bar\" [1 2 3]"), 2);
  // A parameter of the right name but the wrong type is unused too, as in pbrt-v4.
  EXPECT_EQ(warnings_of("WorldBegin\nShape \"sphere\" \"integer radius\" 2"), 1);
  EXPECT_EQ(warnings_of("Film \"rgb\" \"float iso\" 100\nWorldBegin"), 1);
}

// ---------------------------------------------------------------- transforms

TEST(Parser, TranslateScaleRotateCompose) {
  Scene s = parse("WorldBegin\nTranslate 1 2 3\nScale 2 2 2\nRotate 90 0 0 1\nShape \"sphere\"");
  // x -> y (rotation), doubled, then moved: hand-computed columns.
  mat4 expected(vec4(0, 2, 0, 0), vec4(-2, 0, 0, 0), vec4(0, 0, 2, 0), vec4(1, 2, 3, 1));
  const Transform& t = s.shapes[0].render_from_object;
  expect_mat_near(t.m, expected);
  expect_mat_near(t.m * t.m_inv, mat4(1.0f));
  EXPECT_FALSE(s.shapes[0].transform_swaps_handedness);
}

TEST(Parser, TransformAndConcatTransformAreColumnMajor) {
  Scene s = parse(R"(WorldBegin
Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1 ]
ConcatTransform [ 0 0 -1 0  0 1 0 0  1 0 0 0  0 0 0 1 ]
Shape "sphere")");
  // ConcatTransform: rotation about y taking x to -z; then translation by (5,6,7).
  mat4 expected(vec4(0, 0, -1, 0), vec4(0, 1, 0, 0), vec4(1, 0, 0, 0), vec4(5, 6, 7, 1));
  expect_mat_near(s.shapes[0].render_from_object.m, expected);
  EXPECT_EQ(s.shapes[0].render_from_object.point(vec3(1, 0, 0)), vec3(5, 6, 6));
}

TEST(Parser, LookAtAndCameraTransform) {
  Scene s = parse("LookAt 0 0 0  1 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin");
  const Transform& rc = s.camera.render_from_camera;
  // pbrt-v4's camera frame: +z looks along (look - eye), +y is up, +x = up x forward.
  EXPECT_NEAR(glm::length(rc.vector(vec3(0, 0, 1)) - vec3(1, 0, 0)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(rc.vector(vec3(0, 1, 0)) - vec3(0, 1, 0)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(rc.vector(vec3(1, 0, 0)) - vec3(0, 0, -1)), 0.0f, 1e-6f);

  Scene t = parse("LookAt 1 2 3  1 2 4  0 1 0\nCamera \"perspective\"\nWorldBegin");
  expect_mat_near(t.camera.render_from_camera.m, glm::translate(mat4(1.0f), vec3(1, 2, 3)));
}

TEST(Parser, NamedCoordinateSystems) {
  Scene s = parse(R"(Translate 0 0 -5
Camera "perspective"
WorldBegin
Translate 1 0 0
CoordinateSystem "a"
Identity
Scale 3 3 3
CoordSysTransform "a"
Shape "sphere"
CoordSysTransform "camera"
Shape "sphere"
Translate 9 9 9
CoordSysTransform "world"
Shape "sphere")");
  ASSERT_EQ(s.shapes.size(), 3u);
  expect_mat_near(s.shapes[0].render_from_object.m, glm::translate(mat4(1.0f), vec3(1, 0, 0)));
  expect_mat_near(s.shapes[1].render_from_object.m, glm::translate(mat4(1.0f), vec3(0, 0, 5)));
  expect_mat_near(s.camera.render_from_camera.m, glm::translate(mat4(1.0f), vec3(0, 0, 5)));
  expect_mat_near(s.shapes[2].render_from_object.m, mat4(1.0f));
  EXPECT_EQ(warnings_of("WorldBegin\nCoordSysTransform \"nope\""), 1);
}

TEST(Parser, AttributeEndRestoresTheState) {
  Scene s = parse(R"(WorldBegin
Translate 1 0 0
AttributeBegin
  Scale 1 -1 1
  ReverseOrientation
  Material "diffuse" "rgb reflectance" [0.1 0.2 0.3]
  Shape "sphere"
AttributeEnd
TransformBegin
  Translate 0 5 0
TransformEnd
Shape "sphere")");
  ASSERT_EQ(s.shapes.size(), 2u);
  EXPECT_TRUE(s.shapes[0].reverse_orientation);
  EXPECT_TRUE(s.shapes[0].transform_swaps_handedness);
  EXPECT_FALSE(s.shapes[1].reverse_orientation);
  EXPECT_FALSE(s.shapes[1].transform_swaps_handedness);
  expect_mat_near(s.shapes[1].render_from_object.m, glm::translate(mat4(1.0f), vec3(1, 0, 0)));
  EXPECT_NE(s.shapes[0].material, s.shapes[1].material);
  EXPECT_EQ(s.textures[size_t(s.materials[size_t(s.shapes[1].material)].reflectance)].value, RGB(0.5f));
}

TEST(Parser, WorldBeginResetsTheCtm) {
  Scene s = parse("Translate 4 4 4\nWorldBegin\nShape \"sphere\"");
  expect_mat_near(s.shapes[0].render_from_object.m, mat4(1.0f));
}

TEST(Parser, ActiveTransformEndTimeIsIgnoredWithOneWarning) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
ActiveTransform EndTime
Translate 5 0 0
ActiveTransform All
Translate 1 0 0
ActiveTransform EndTime
Translate 7 0 0
ActiveTransform StartTime
Shape "sphere")");
  EXPECT_EQ(warning_count() - before, 1);
  expect_mat_near(s.shapes[0].render_from_object.m, glm::translate(mat4(1.0f), vec3(1, 0, 0)));
}

// ---------------------------------------------------------------- shapes

TEST(Parser, TriangleMeshIsBakedIntoRenderSpace) {
  Scene s = parse(std::string("WorldBegin\nTranslate 0 0 1\nScale 2 1 1\n") +
                  R"(Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "normal N" [1 1 0 1 1 0 1 1 0]
  "point2 uv" [0 0 1 0 0 1] "integer indices" [0 1 2])");
  ASSERT_EQ(s.meshes.size(), 1u);
  const TriangleMesh& m = s.meshes[0];
  EXPECT_EQ(m.p[1], vec3(2, 0, 1));
  EXPECT_EQ(m.n[0], vec3(0.5f, 1, 0));  // inverse transpose of the scale
  EXPECT_EQ(m.uv[2], vec2(0, 1));
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_TRUE(s.shapes[0].render_from_object.is_identity());
  EXPECT_EQ(s.top_level_shapes, std::vector<int>{0});
}

TEST(Parser, ReverseOrientationFlipsMeshNormals) {
  Scene s = parse(std::string("WorldBegin\nReverseOrientation\n") + kTri);
  EXPECT_EQ(s.meshes[0].n[0], vec3(0, 0, -1));
  EXPECT_TRUE(s.shapes[0].reverse_orientation);
  Scene t = parse(std::string("WorldBegin\n") + kTri);
  EXPECT_EQ(t.meshes[0].n[0], vec3(0, 0, 1));
}

TEST(Parser, MeshWarningsForMismatchedArraysAndTangents) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "normal N" [0 0 1] "vector3 S" [1 0 0 1 0 0 1 0 0])");
  EXPECT_EQ(warning_count() - before, 2);
  EXPECT_TRUE(s.meshes[0].n.empty());
  EXPECT_EQ(s.meshes[0].indices.size(), 3u);
}

TEST(Parser, SphereDiskAndUnsupportedShapes) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
Shape "sphere" "float radius" 2 "float zmin" -1 "float zmax" 1.5 "float phimax" 180
Shape "disk" "float height" 0.5 "float radius" 3 "float innerradius" 1 "float phimax" 90
Shape "cylinder" "float radius" 0.5 "float zmax" 2 "float phimax" 270
Shape "nurbs" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3])");
  EXPECT_EQ(warning_count() - before, 1);  // the unknown shape only
  ASSERT_EQ(s.shapes.size(), 3u);
  EXPECT_EQ(s.shapes[2].kind, ShapeKind::Cylinder);
  EXPECT_FLOAT_EQ(s.shapes[2].cylinder.radius, 0.5f);
  EXPECT_FLOAT_EQ(s.shapes[2].cylinder.zmin, -1);  // pbrt-v4's defaults: -1 and 1, whatever the radius
  EXPECT_FLOAT_EQ(s.shapes[2].cylinder.zmax, 2);
  EXPECT_FLOAT_EQ(s.shapes[2].cylinder.phimax, 270);
  EXPECT_FLOAT_EQ(s.shapes[0].sphere.radius, 2);
  EXPECT_FLOAT_EQ(s.shapes[0].sphere.zmin, -1);
  EXPECT_FLOAT_EQ(s.shapes[0].sphere.zmax, 1.5f);
  EXPECT_FLOAT_EQ(s.shapes[0].sphere.phimax, 180);
  EXPECT_EQ(s.shapes[1].kind, ShapeKind::Disk);
  EXPECT_FLOAT_EQ(s.shapes[1].disk.height, 0.5f);
  EXPECT_FLOAT_EQ(s.shapes[1].disk.innerradius, 1);
  EXPECT_FLOAT_EQ(s.shapes[1].disk.phimax, 90);
  // zmin/zmax default to -radius/radius.
  Scene d = parse("WorldBegin\nShape \"sphere\" \"float radius\" 3");
  EXPECT_FLOAT_EQ(d.shapes[0].sphere.zmin, -3);
  EXPECT_FLOAT_EQ(d.shapes[0].sphere.zmax, 3);
}

TEST(Parser, BilinearMeshPlanarAndCurvedPatches) {
  Scene s = parse(R"(WorldBegin
Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 0]
Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 1] "point2 uv" [0 0 2 0 0 2 2 2])");
  ASSERT_EQ(s.meshes.size(), 2u);
  const TriangleMesh& flat = s.meshes[0];
  EXPECT_EQ(flat.triangle_count(), 2u);
  EXPECT_EQ(flat.p.size(), 4u);
  EXPECT_TRUE(flat.n.empty());
  EXPECT_EQ(flat.uv[3], vec2(1, 1));  // default uv: the patch's (u, v)
  // Winding follows dp/du x dp/dv = +z.
  vec3 a = flat.p[flat.indices[0]], b = flat.p[flat.indices[1]], c = flat.p[flat.indices[2]];
  EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f);

  const TriangleMesh& curved = s.meshes[1];
  EXPECT_EQ(curved.triangle_count(), 2u * 16u * 16u);
  ASSERT_EQ(curved.p.size(), 17u * 17u);
  ASSERT_EQ(curved.n.size(), curved.p.size());
  // Centre vertex (u = v = 1/2): bilinear position, interpolated uv, surface normal.
  size_t centre = 8 * 17 + 8;
  EXPECT_NEAR(glm::length(curved.p[centre] - vec3(0.5f, 0.5f, 0.25f)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(curved.uv[centre] - vec2(1, 1)), 0.0f, 1e-6f);
  // dp/du = (1, 0, v), dp/dv = (0, 1, u): normal (-v, -u, 1) normalised.
  EXPECT_NEAR(glm::length(curved.n[centre] - glm::normalize(vec3(-0.5f, -0.5f, 1))), 0.0f, 1e-5f);
}

TEST(Parser, BilinearNormalsFollowOrientation) {
  const char* curved = R"(Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 1])";
  Scene rev = parse(std::string("WorldBegin\nReverseOrientation\n") + curved);
  EXPECT_NEAR(glm::length(rev.meshes[0].n[0] - vec3(0, 0, -1)), 0.0f, 1e-6f);
  // A mirror flips the cross product and the handedness flag together: the normal keeps facing +z's image.
  Scene mir = parse(std::string("WorldBegin\nScale 1 1 -1\n") + curved);
  EXPECT_NEAR(glm::length(mir.meshes[0].n[0] - vec3(0, 0, -1)), 0.0f, 1e-6f);
  // Given normals are interpolated (and baked, then flipped by ReverseOrientation like trianglemesh's).
  Scene given = parse(std::string("WorldBegin\nReverseOrientation\n") + curved +
                      R"( "normal N" [0 0 1 0 0 1 1 0 0 1 0 0])");
  EXPECT_NEAR(glm::length(given.meshes[0].n[8 * 17 + 8] - vec3(-0.5f, 0, -0.5f)), 0.0f, 1e-6f);
}

TEST(Parser, TriangleMeshWithoutIndicesNeedsExactlyThreeVertices) {
  Scene s = parse("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]");
  EXPECT_EQ(s.meshes[0].indices, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1]"),
            "test.pbrt:2:1: error: trianglemesh without \"integer indices\", expected indices unless there are exactly 3 vertices");
  EXPECT_EQ(error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 3]"),
            "test.pbrt:2:53: error: index 3 in \"integer indices\", expected an index below the 3 vertices");
}

TEST(Parser, AlphaIsRecordedAsAFloatTextureOnEveryShape) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
Texture "mask" "float" "constant" "float value" 0.25
Shape "sphere" "float alpha" 0.5
Shape "sphere" "texture alpha" "mask")");
  EXPECT_EQ(warning_count() - before, 0);
  ASSERT_GE(s.shapes[0].alpha, 0);
  EXPECT_TRUE(s.textures[size_t(s.shapes[0].alpha)].is_float);
  EXPECT_FLOAT_EQ(s.textures[size_t(s.shapes[0].alpha)].value.x, 0.5f);
  EXPECT_EQ(s.textures[size_t(s.shapes[1].alpha)].name, "mask");
}

TEST(Parser, ShapeAttributesAreDefaults) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
AttributeBegin
Attribute "shape" "float radius" 3 "float unusedbyspheres" 1
Shape "sphere"
Shape "sphere" "float radius" 4
AttributeEnd
Shape "sphere")");
  EXPECT_EQ(warning_count() - before, 0);
  EXPECT_FLOAT_EQ(s.shapes[0].sphere.radius, 3);
  EXPECT_FLOAT_EQ(s.shapes[1].sphere.radius, 4);
  EXPECT_FLOAT_EQ(s.shapes[2].sphere.radius, 1);
}

// ---------------------------------------------------------------- instancing

TEST(Parser, ObjectInstancesReferencePrototypes) {
  Scene s = parse(std::string(R"(WorldBegin
AttributeBegin
Translate 0 0 2
ObjectBegin "tri"
)") + kTri + R"(
Shape "sphere"
ObjectEnd
AttributeEnd
Shape "sphere"
Translate 10 0 0
ObjectInstance "tri"
Translate 10 0 0
ObjectInstance "tri")");
  ASSERT_EQ(s.prototypes.size(), 1u);
  EXPECT_EQ(s.prototypes[0].name, "tri");
  EXPECT_EQ(s.prototypes[0].shapes, (std::vector<int>{0, 1}));
  EXPECT_EQ(s.top_level_shapes, std::vector<int>{2});
  // The prototype's mesh is baked with the CTM of its definition.
  EXPECT_EQ(s.meshes[0].p[1], vec3(1, 0, 2));
  ASSERT_EQ(s.instances.size(), 2u);
  EXPECT_EQ(s.instances[1].prototype, 0);
  expect_mat_near(s.instances[0].render_from_instance.m, glm::translate(mat4(1.0f), vec3(10, 0, 0)));
  expect_mat_near(s.instances[1].render_from_instance.m, glm::translate(mat4(1.0f), vec3(20, 0, 0)));
}

TEST(Parser, AreaLightsInsideObjectsWarnAndDoNotEmit) {
  int before = warning_count();
  Scene s = parse(std::string("WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\nObjectBegin \"o\"\n") + kTri +
                  "\nObjectEnd\nAttributeEnd");
  EXPECT_EQ(warning_count() - before, 1);
  EXPECT_TRUE(s.lights.empty());
  EXPECT_EQ(s.shapes[0].area_light, -1);
}

// ---------------------------------------------------------------- materials and textures

TEST(Parser, MaterialsBecomeReflectanceTextures) {
  Scene s = parse(R"(WorldBegin
Texture "checks" "spectrum" "checkerboard" "rgb tex1" [1 0 0] "rgb tex2" [0 0 1]
MakeNamedMaterial "red" "string type" "diffuse" "rgb reflectance" [0.8 0.1 0.1]
MakeNamedMaterial "tex" "string type" [ "diffuse" ] "texture reflectance" "checks"
Shape "sphere"
NamedMaterial "red"
Shape "sphere"
NamedMaterial "tex"
Shape "sphere"
Material "diffuse"
Shape "sphere"
Material "diffuse" "spectrum reflectance" [300 0.3 800 0.3]
Shape "sphere")");
  auto refl = [&](int shape) { return s.materials[size_t(s.shapes[size_t(shape)].material)].reflectance; };
  EXPECT_EQ(s.textures[size_t(refl(0))].value, RGB(0.5f));  // default material
  EXPECT_EQ(s.textures[size_t(refl(0))].kind, TextureKind::Constant);
  expect_scene_color(s.textures[size_t(refl(1))].value, RGB(0.8f, 0.1f, 0.1f));
  EXPECT_EQ(s.materials[size_t(s.shapes[1].material)].name, "red");
  EXPECT_EQ(s.textures[size_t(refl(2))].name, "checks");
  EXPECT_EQ(s.textures[size_t(refl(3))].value, RGB(0.5f));
  RGB grey = s.textures[size_t(refl(4))].value;
  EXPECT_NEAR(grey.x, 0.3f, 1e-4f);
  EXPECT_NEAR(grey.y, 0.3f, 1e-4f);
  EXPECT_NEAR(grey.z, 0.3f, 1e-4f);
}

TEST(Parser, UnsupportedMaterialsWarnOnceAndSubstituteDiffuse) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
MakeNamedMaterial "metal" "string type" "conductor" "spectrum eta" "metal-Cu-eta" "float roughness" 0.1
Material "measured" "string filename" "skin.bsdf"
Shape "sphere"
NamedMaterial "metal"
Shape "sphere")");
  EXPECT_EQ(warning_count() - before, 1);
  EXPECT_EQ(s.materials[size_t(s.shapes[0].material)].kind, MaterialKind::Diffuse);
  EXPECT_EQ(s.textures[size_t(s.materials[size_t(s.shapes[0].material)].reflectance)].value, RGB(0.5f));
  EXPECT_EQ(s.materials[size_t(s.shapes[1].material)].kind, MaterialKind::Conductor);
  EXPECT_EQ(error_of("WorldBegin\nMakeNamedMaterial \"m\" \"float roughness\" 0"),
            "test.pbrt:2:1: error: MakeNamedMaterial \"m\" without \"string type\", expected the material type");
}

TEST(Parser, TexturesOfEveryClass) {
  TempDir dir;
  dir.write("tex/wood.png", "not really a png; the parser does not load images");
  Scene s = parse_scene_string(R"(WorldBegin
Texture "img" "spectrum" "imagemap" "string filename" "tex/wood.png" "string wrap" "clamp" "float scale" 2
  "bool invert" true "string encoding" "gamma 2.2" "float uscale" 4 "float vscale" 5 "float udelta" 0.5 "float vdelta" 0.25
Texture "img2" "float" "imagemap" "string filename" "tex/wood.png" "string encoding" "gamma 2.2" "string filter" "bilinear"
Texture "img3" "float" "imagemap" "string filename" "tex/../tex/wood.png"
Texture "amt" "float" "constant" "float value" 0.75
Texture "sc" "spectrum" "scale" "texture tex" "img" "float scale" 3
Texture "mx" "spectrum" "mix" "rgb tex1" [1 1 0] "texture tex2" "sc" "texture amount" "amt"
Texture "bb" "spectrum" "constant" "blackbody value" 6500
)", "test.pbrt", dir.path.string());
  ASSERT_EQ(s.images.size(), 3u);  // deduplicated by (path, encoding, colour or data)
  EXPECT_TRUE(s.images[0].is_color);
  EXPECT_FALSE(s.images[1].is_color);
  EXPECT_EQ(s.images[0].filename, fs::absolute(dir.path / "tex/wood.png").lexically_normal().string());
  EXPECT_EQ(s.images[0].encoding, "gamma 2.2");
  EXPECT_EQ(s.images[1].encoding, "gamma 2.2");
  EXPECT_EQ(s.images[2].encoding, "");
  EXPECT_TRUE(s.images[0].pixels.empty());
  auto find = [&](const std::string& n) -> const Texture& {
    for (const Texture& t : s.textures)
      if (t.name == n) return t;
    throw std::runtime_error("no texture " + n);
  };
  const Texture& img = find("img");
  EXPECT_EQ(img.kind, TextureKind::ImageMap);
  EXPECT_EQ(img.image, 0);
  EXPECT_EQ(img.wrap, WrapMode::Clamp);
  EXPECT_FLOAT_EQ(img.scale, 2);
  EXPECT_TRUE(img.invert);
  EXPECT_FLOAT_EQ(img.mapping.su, 4);
  EXPECT_FLOAT_EQ(img.mapping.sv, 5);
  EXPECT_FLOAT_EQ(img.mapping.du, 0.5f);
  EXPECT_FLOAT_EQ(img.mapping.dv, 0.25f);
  EXPECT_EQ(find("img").image, 0);
  EXPECT_EQ(find("img2").image, 1);  // same file and encoding, but data rather than colour
  EXPECT_TRUE(find("img2").is_float);
  EXPECT_EQ(find("img3").image, 2);
  const Texture& sc = find("sc");
  EXPECT_EQ(sc.kind, TextureKind::Scale);
  EXPECT_EQ(s.textures[size_t(sc.tex1)].name, "img");
  EXPECT_FLOAT_EQ(s.textures[size_t(sc.tex2)].value.x, 3);
  const Texture& mx = find("mx");
  EXPECT_EQ(mx.kind, TextureKind::Mix);
  expect_scene_color(s.textures[size_t(mx.tex1)].value, RGB(1, 1, 0));
  EXPECT_EQ(s.textures[size_t(mx.tex2)].name, "sc");
  EXPECT_EQ(s.textures[size_t(mx.amount)].name, "amt");
  EXPECT_NEAR(luminance(find("bb").value), 1.0f, 1e-3f);
}

TEST(Parser, CheckerboardAndTextureWarnings) {
  int before = warning_count();
  Scene s = parse(R"(WorldBegin
Texture "c" "float" "checkerboard" "float tex1" 0.2 "float tex2" 0.7 "integer dimension" 3 "string mapping" "spherical"
Texture "p" "spectrum" "ptex" "string filename" "a.ptx")");
  // A 3D checkerboard has no 2D mapping, so "mapping" goes unused; ptex is substituted.
  EXPECT_EQ(warning_count() - before, 2);
  const Texture& c = s.textures.back().name == "p" ? s.textures[s.textures.size() - 2] : s.textures.back();
  EXPECT_EQ(c.kind, TextureKind::Checkerboard);
  EXPECT_EQ(c.mapping_kind, TextureMappingKind::Point3D);
  EXPECT_FLOAT_EQ(s.textures[size_t(c.tex1)].value.x, 0.2f);
  EXPECT_FLOAT_EQ(s.textures[size_t(c.tex2)].value.x, 0.7f);
}

// ---------------------------------------------------------------- lights

TEST(Parser, AreaLightsApplyToLaterShapesInTheirScope) {
  Scene s = parse(std::string(R"(WorldBegin
Shape "sphere"
AttributeBegin
AreaLightSource "diffuse" "rgb L" [1 2 3] "float scale" 2 "bool twosided" true "bool virtual" "true"
Shape "sphere"
)") + kTri + R"(
AttributeEnd
Shape "sphere")");
  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_EQ(s.shapes[0].area_light, -1);
  EXPECT_EQ(s.shapes[3].area_light, -1);
  for (int i = 0; i < 2; ++i) {
    const Light& l = s.lights[size_t(i)];
    EXPECT_EQ(l.kind, LightKind::Area);
    EXPECT_EQ(l.shape, i + 1);
    EXPECT_EQ(s.shapes[size_t(i + 1)].area_light, i);
    expect_scene_color(l.L, RGB(2, 4, 6));
    EXPECT_TRUE(l.two_sided);
    EXPECT_TRUE(l.is_virtual);
  }
  EXPECT_EQ(warnings_of("WorldBegin\nAreaLightSource \"diffuse\" \"float power\" 10\nShape \"sphere\""), 0);
}

// pbrt-v4's "power": L *= power / (pi * sides * area), area per shape (per
// triangle for meshes, as pbrt-v4 makes one light per triangle).
TEST(Parser, AreaLightPowerNormalisesByAreaAndPi) {
  Scene s = parse(R"(WorldBegin
AttributeBegin
AreaLightSource "diffuse" "rgb L" [1 2 3] "float power" 10 "float scale" 2
Shape "sphere" "float radius" 2
AttributeEnd
AttributeBegin
AreaLightSource "diffuse" "float power" 10 "bool twosided" true
Shape "trianglemesh" "point3 P" [0 0 0 2 0 0 2 2 0 0 2 0] "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
AreaLightSource "diffuse" "float power" 10
Shape "disk" "float radius" 1 "float innerradius" 0.5 "float phimax" 180
AttributeEnd)");
  ASSERT_EQ(s.lights.size(), 3u);
  const float sphere_area = 4.0f * kPi * 4.0f;
  expect_scene_color(s.lights[0].L, RGB(1, 2, 3) * (2.0f * 10.0f / (kPi * sphere_area)));
  // Two triangles of area 2, two-sided: each emits the power, as in pbrt-v4.
  expect_scene_color(s.lights[1].L, RGB(10.0f / (kPi * 2.0f * 2.0f)));
  const float disk_area = 0.5f * kPi * (1.0f - 0.25f);
  expect_scene_color(s.lights[2].L, RGB(10.0f / (kPi * disk_area)));
}

TEST(Parser, PointSpotDistantPowerAndIlluminance) {
  Scene s = parse(R"(WorldBegin
LightSource "point" "rgb I" [1 1 1] "float power" 8
LightSource "spot" "rgb I" [2 2 2] "float power" 8 "float coneangle" 40 "float conedeltaangle" 10
  "point3 from" [1 0 0] "point3 to" [1 0 -5]
AttributeBegin
Rotate 90 0 1 0
LightSource "distant" "rgb L" [1 1 1] "float illuminance" 3 "point3 from" [0 0 1] "point3 to" [0 0 0]
AttributeEnd
LightSource "infinite" "rgb L" [1 1 1] "float illuminance" 2)");
  ASSERT_EQ(s.lights.size(), 4u);
  EXPECT_NEAR(s.lights[0].L.x, 8.0f / (4.0f * kPi), 1e-6f);
  const Light& spot = s.lights[1];
  EXPECT_EQ(spot.kind, LightKind::Spot);
  EXPECT_EQ(spot.position, vec3(1, 0, 0));
  EXPECT_NEAR(glm::length(spot.direction - vec3(0, 0, -1)), 0.0f, 1e-6f);
  float cs = std::cos(radians(30.0f)), ce = std::cos(radians(40.0f));
  EXPECT_NEAR(spot.cos_falloff_start, cs, 1e-6f);
  EXPECT_NEAR(spot.cos_falloff_end, ce, 1e-6f);
  EXPECT_NEAR(spot.L.x, 2.0f * 8.0f / (2.0f * kPi * ((1.0f - cs) + (cs - ce) / 2.0f)), 1e-4f);
  const Light& distant = s.lights[2];
  EXPECT_EQ(distant.kind, LightKind::Distant);
  EXPECT_NEAR(glm::length(distant.direction - vec3(1, 0, 0)), 0.0f, 1e-6f);  // from - to, rotated
  EXPECT_NEAR(distant.L.x, 3.0f, 1e-6f);
  EXPECT_NEAR(s.lights[3].L.x, 2.0f / kPi, 1e-6f);
}

TEST(Parser, BlackbodyLightIsLuminanceNormalised) {
  Scene s = parse("WorldBegin\nAreaLightSource \"diffuse\" \"blackbody L\" 6500 \"float scale\" 5\nShape \"sphere\"");
  RGB L = s.lights[0].L;
  EXPECT_NEAR(luminance(L), 5.0f, 1e-3f);
  EXPECT_NEAR(L.x / L.y, 1.0f, 0.1f);
  EXPECT_NEAR(L.z / L.y, 1.0f, 0.1f);
}

TEST(Parser, PointAndInfiniteLights) {
  TempDir dir;
  dir.write("sky.exr", "x");
  int before = warning_count();
  Scene s = parse_scene_string(R"(WorldBegin
AttributeBegin
Translate 1 2 3
LightSource "point" "rgb I" [1 1 1] "float scale" 4 "point3 from" [0 0 1]
Rotate 90 1 0 0
LightSource "infinite" "string filename" "sky.exr" "float scale" 0.5
AttributeEnd
LightSource "infinite" "rgb L" [0.1 0.2 0.3]
)", "test.pbrt", dir.path.string());
  EXPECT_EQ(warning_count() - before, 0);
  ASSERT_EQ(s.lights.size(), 3u);
  EXPECT_EQ(s.lights[0].kind, LightKind::Point);
  EXPECT_EQ(s.lights[0].position, vec3(1, 2, 4));
  expect_scene_color(s.lights[0].L, RGB(4.0f));
  EXPECT_EQ(s.lights[1].kind, LightKind::Infinite);
  EXPECT_EQ(s.lights[1].image, 0);
  EXPECT_EQ(s.lights[1].L, RGB(0.5f));
  EXPECT_NEAR(glm::length(s.lights[1].render_from_light.vector(vec3(0, 1, 0)) - vec3(0, 0, 1)), 0.0f, 1e-6f);
  EXPECT_EQ(s.lights[2].image, -1);
  expect_scene_color(s.lights[2].L, RGB(0.1f, 0.2f, 0.3f));
}

TEST(Spectrum, Blackbody6500IsNearWhiteWithLuminanceOne) {
  RGB c = blackbody_rgb(6500.0f);
  EXPECT_NEAR(luminance(srgb_to_working(c)), 1.0f, 1e-4f);
  EXPECT_NEAR(c.x, 1.0f, 0.06f);
  EXPECT_NEAR(c.y, 1.0f, 0.06f);
  EXPECT_NEAR(c.z, 1.0f, 0.06f);
  // Cooler is redder, hotter is bluer.
  EXPECT_GT(blackbody_rgb(2700.0f).x, blackbody_rgb(2700.0f).z);
  EXPECT_LT(blackbody_rgb(10000.0f).x, blackbody_rgb(10000.0f).z);
}

TEST(Spectrum, IlluminantAndReflectanceNormalisation) {
  std::vector<float> lambda = {400, 700}, value = {3, 3};
  EXPECT_NEAR(luminance(srgb_to_working(spectrum_to_rgb_illuminant(lambda, value))), 1.0f, 1e-4f);
  std::vector<float> wide = {300, 900}, half = {0.5f, 0.5f};
  RGB r = spectrum_to_rgb_reflectance(wide, half);
  EXPECT_NEAR(glm::length(r - RGB(0.5f)), 0.0f, 1e-4f);
  // A reflectance confined to long wavelengths is red.
  std::vector<float> red_l = {600, 601, 830}, red_v = {0, 0.9f, 0.9f};
  RGB red = spectrum_to_rgb_reflectance(red_l, red_v);
  EXPECT_GT(red.x, 5.0f * std::max(red.y, red.z));
  // The CMF fit peaks where the CIE tables do.
  EXPECT_NEAR(cie_xyz_cmf(555.0f).y, 1.0f, 0.02f);
  ASSERT_NE(find_named_spectrum("stdillum-A"), nullptr);
  const NamedSpectrum* bk7 = find_named_spectrum("glass-BK7");
  ASSERT_NE(bk7, nullptr);
  EXPECT_NEAR(spectrum_at(bk7->lambda, bk7->value, 550.0f), 1.5185f, 1e-3f);
  EXPECT_EQ(find_named_spectrum("glass-unobtainium"), nullptr);
}

// ---------------------------------------------------------------- files

TEST(Parser, IncludeAndPlyPathsAreRelativeToTheIncludingFile) {
  TempDir dir;
  dir.write("main.pbrt", "Film \"rgb\" \"integer xresolution\" 10\nInclude \"parts/world.pbrt\"\n");
  dir.write("parts/inner/shapes.pbrt", "NamedMaterial \"m\"\nShape \"plymesh\" \"string filename\" \"tri.ply\"\n");
  dir.write("parts/inner/tri.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  // NamedMaterial in an included file must see materials defined before.
  std::string main = dir.path.string() + "/main.pbrt";
  std::string text = "MakeNamedMaterial \"m\" \"string type\" \"diffuse\"\n";
  dir.write("parts/world.pbrt", "WorldBegin\n" + text + "Include \"inner/shapes.pbrt\"\nImport \"inner/shapes.pbrt\"\n");
  Scene s = load_scene(main);
  EXPECT_EQ(s.path, fs::absolute(main).lexically_normal().string());
  EXPECT_EQ(s.film.width, 10);
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(s.meshes[0].p[1], vec3(1, 0, 0));
  EXPECT_EQ(s.materials[size_t(s.shapes[0].material)].name, "m");
}

TEST(Parser, ErrorsInIncludedFilesNameThatFile) {
  TempDir dir;
  std::string inc = dir.write("inc.pbrt", "\n  Bogus 1\n");
  EXPECT_EQ(error_of("WorldBegin\nInclude \"inc.pbrt\"", dir.path.string()),
            inc + ":2:3: error: unknown directive \"Bogus\", expected a pbrt-v4 directive");
}

TEST(Parser, MissingFilesNameTheIncludingLocation) {
  TempDir dir;
  std::string base = dir.path.string();
  std::string missing = (dir.path / "nope.pbrt").string();
  EXPECT_EQ(error_of("WorldBegin\n  Include \"nope.pbrt\"", base),
            "test.pbrt:2:3: error: cannot open \"" + missing + "\": No such file or directory, expected a readable file");
  EXPECT_EQ(error_of("WorldBegin\nImport \"nope.pbrt\"", base),
            "test.pbrt:2:1: error: cannot open \"" + missing + "\": No such file or directory, expected a readable file");
  EXPECT_EQ(error_of("WorldBegin\nShape \"plymesh\" \"string filename\" \"m.ply\"", base),
            "test.pbrt:2:1: error: PLY file \"" + (dir.path / "m.ply").string() + "\" not found, expected an existing file");
  EXPECT_EQ(error_of("WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"i.png\"", base),
            "test.pbrt:2:35: error: image \"" + (dir.path / "i.png").string() + "\" not found, expected an existing file");
  EXPECT_THROW(load_scene(missing), Error);
}

// ---------------------------------------------------------------- errors

TEST(ParserErrors, LexicalErrors) {
  EXPECT_EQ(error_of("WorldBegin\nFoo 1"), "test.pbrt:2:1: error: unknown directive \"Foo\", expected a pbrt-v4 directive");
  EXPECT_EQ(error_of("Film \"rgb"), "test.pbrt:1:6: error: unterminated string, expected a closing '\"' on the same line");
  EXPECT_EQ(error_of("Film \"rgb\n\""), "test.pbrt:1:6: error: unterminated string, expected a closing '\"' on the same line");
  EXPECT_EQ(error_of("Translate 1 2 x"), "test.pbrt:1:15: error: bad number \"x\" for Translate, expected a number");
  EXPECT_EQ(error_of("Camera \"perspective\" \"float fov\" [ 1.2.3 ]"),
            "test.pbrt:1:36: error: bad number \"1.2.3\" for \"float fov\", expected a number");
  EXPECT_EQ(error_of("Film \"rgb\" \"integer xresolution\" 1.5"),
            "test.pbrt:1:34: error: value 1.5 for \"integer xresolution\", expected an integer");
  EXPECT_EQ(error_of("[ 1 ]"), "test.pbrt:1:1: error: unexpected [, expected a directive");
}

TEST(ParserErrors, ParameterErrors) {
  EXPECT_EQ(error_of("Camera \"perspective\" \"flot fov\" 3"),
            "test.pbrt:1:22: error: unknown parameter type \"flot\" in \"flot fov\", expected one of integer, float, "
            "point2, vector2, point3, vector3, normal3, rgb, spectrum, blackbody, bool, string, texture");
  EXPECT_EQ(error_of("WorldBegin\nMaterial \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 ]"),
            "test.pbrt:2:20: error: \"rgb reflectance\" has 2 values, expected a multiple of 3");
  EXPECT_EQ(error_of("Camera \"perspective\" \"float fov\" \"abc\""),
            "test.pbrt:1:34: error: value \"abc\" for \"float fov\", expected a number");
  EXPECT_EQ(error_of("Film \"rgb\" \"string filename\" [ 3 ]"),
            "test.pbrt:1:32: error: value 3 for \"string filename\", expected a quoted string");
  EXPECT_EQ(error_of("WorldBegin\nAreaLightSource \"diffuse\" \"bool twosided\" \"yes\""),
            "test.pbrt:2:43: error: value \"yes\" for \"bool twosided\", expected true or false");
  EXPECT_EQ(error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [ 0 0 0\n  1 0 0 "),
            "test.pbrt:3:9: error: unexpected end of file inside the value list of \"point3 P\" opened at line 2, expected ']'");
  EXPECT_EQ(error_of("Transform [ 1 0 0"), "test.pbrt:1:18: error: unexpected end of file inside the list of Transform, expected ']'");
  EXPECT_EQ(error_of("Camera \"perspective\" \"float fov\""),
            "test.pbrt:1:33: error: unexpected end of file after \"float fov\", expected its value");
}

TEST(ParserErrors, BlockStructureErrors) {
  EXPECT_EQ(error_of("WorldBegin\nAttributeEnd"), "test.pbrt:2:1: error: AttributeEnd without AttributeBegin");
  EXPECT_EQ(error_of("WorldBegin\nObjectEnd"), "test.pbrt:2:1: error: ObjectEnd without ObjectBegin");
  EXPECT_EQ(error_of("WorldBegin\nObjectBegin \"a\"\nAttributeBegin\nObjectEnd"),
            "test.pbrt:4:1: error: ObjectEnd while AttributeBegin at test.pbrt:3:1 is open, expected its end first");
  EXPECT_EQ(error_of("WorldBegin\nAttributeBegin\nShape \"sphere\""),
            "test.pbrt:2:1: error: AttributeBegin without its end, expected it closed before the end of the scene");
  EXPECT_EQ(error_of("Film \"rgb\""), "test.pbrt:1:11: error: end of the scene before WorldBegin, expected WorldBegin");
  EXPECT_EQ(error_of("WorldBegin\nCamera \"perspective\""),
            "test.pbrt:2:1: error: Camera after WorldBegin, expected it before WorldBegin");
  EXPECT_EQ(error_of("Shape \"sphere\"\nWorldBegin"), "test.pbrt:1:1: error: Shape before WorldBegin, expected it after WorldBegin");
  EXPECT_EQ(error_of("WorldBegin\nWorldBegin"), "test.pbrt:2:1: error: WorldBegin after WorldBegin, expected it before WorldBegin");
}

TEST(ParserErrors, UnknownNames) {
  EXPECT_EQ(error_of("WorldBegin\nNamedMaterial \"gold\""),
            "test.pbrt:2:1: error: unknown named material \"gold\", expected a name defined by MakeNamedMaterial");
  EXPECT_EQ(error_of("WorldBegin\nMaterial \"diffuse\" \"texture reflectance\" \"wood\""),
            "test.pbrt:2:20: error: unknown spectrum texture \"wood\", expected a texture declared earlier with Texture");
  // Float and spectrum textures have separate names, as in pbrt-v4.
  EXPECT_EQ(error_of("WorldBegin\nTexture \"f\" \"float\" \"constant\"\nMaterial \"diffuse\" \"texture reflectance\" \"f\""),
            "test.pbrt:3:20: error: unknown spectrum texture \"f\", expected a texture declared earlier with Texture");
  EXPECT_EQ(error_of("WorldBegin\nObjectInstance \"car\""),
            "test.pbrt:2:1: error: unknown object \"car\", expected a name defined by ObjectBegin");
  EXPECT_EQ(error_of("WorldBegin\nTexture \"t\" \"color\" \"constant\""),
            "test.pbrt:2:1: error: texture type \"color\", expected \"float\" or \"spectrum\"");
}

TEST(Parser, ParsesLargeMeshesWithoutAllocatingPerToken) {
  // 300k vertices as text (about 6 MB, 1.2M numbers): the tokenizer must not
  // allocate per token (how fast it parses is the benchmarks' business).
  std::string text = "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [";
  constexpr int kVerts = 300000;
  for (int i = 0; i < kVerts; ++i) text += fmt::format(" 0.125 -1.5e-3 {}", i);
  text += " ] \"integer indices\" [";
  for (int i = 0; i + 2 < kVerts; i += 3) text += fmt::format(" {} {} {}", i, i + 1, i + 2);
  text += " ]\n";
  const uint64_t before = test::thread_allocations();
  Scene s = parse(text);
  const uint64_t allocations = test::thread_allocations() - before;
  ASSERT_EQ(s.meshes[0].p.size(), size_t(kVerts));
  EXPECT_EQ(s.meshes[0].p[kVerts - 1], vec3(0.125f, -1.5e-3f, float(kVerts - 1)));
  std::printf("parsing 1.2M numbers: %llu allocations\n", (unsigned long long)allocations);
  EXPECT_GT(allocations, 0u);  // the mesh's arrays: the count is live
  EXPECT_LT(allocations, 10000u);
}

// ---------------------------------------------------------------- hostile input

TEST(Parser, TransformArgumentsMustBeFinite) {
  EXPECT_EQ(error_of("Translate 0 0 nan\nWorldBegin"),
            "test.pbrt:1:15: error: non-finite number \"nan\" for Translate, expected a finite number");
  EXPECT_EQ(error_of("Scale 1 inf 1\nWorldBegin"),
            "test.pbrt:1:9: error: non-finite number \"inf\" for Scale, expected a finite number");
  EXPECT_EQ(error_of("Rotate 1e39 0 0 1\nWorldBegin"),
            "test.pbrt:1:8: error: out-of-range number \"1e39\" for Rotate, expected a finite number");
  EXPECT_EQ(error_of("LookAt 0 0 -5  0 0 0  0 0 0\nWorldBegin"),
            "test.pbrt:1:1: error: LookAt with a zero up vector, expected a non-zero up vector");
}

TEST(Parser, TheCameraTransformMustBeInvertible) {
  const std::string expected =
      "error: the camera transform is not invertible or not finite (a zero scale, a zero Transform, a huge value?), "
      "expected an invertible transform";
  EXPECT_EQ(error_of("Scale 0 0 0\nCamera \"perspective\"\nWorldBegin"), "test.pbrt:2:1: " + expected);
  EXPECT_EQ(error_of("Transform [0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0]\nCamera \"perspective\"\nWorldBegin"),
            "test.pbrt:2:1: " + expected);
  EXPECT_EQ(error_of("Scale 1e15 1e15 1e15\nScale 1e15 1 1\nCamera \"perspective\"\nWorldBegin"),
            "test.pbrt:3:1: " + expected);
  EXPECT_EQ(error_of("Scale 2 2 2\nCamera \"perspective\"\nWorldBegin"), "no error");
}

TEST(Parser, ShapesUnderADegenerateTransformAreDroppedWithAWarning) {
  std::string text = std::string("WorldBegin\nAttributeBegin\nScale 0 0 0\n") + kTri +
                     "\nShape \"sphere\"\nAttributeEnd\n" + kTri + "\n";
  EXPECT_EQ(warnings_of(text), 2);
  Scene s = parse(text);
  EXPECT_EQ(s.shapes.size(), 1u);  // the triangle after AttributeEnd
}

TEST(Parser, IncludeCyclesAreErrorsNamingTheChain) {
  TempDir dir;
  std::string self = dir.write("self.pbrt", "Include \"self.pbrt\"\n");
  dir.write("a.pbrt", "WorldBegin\nInclude \"b.pbrt\"\n");
  dir.write("b.pbrt", "\n  Include \"a.pbrt\"\n");
  auto error_loading = [](const std::string& path) {
    try {
      load_scene(path);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string d = fs::weakly_canonical(dir.path).string();
  EXPECT_EQ(error_loading(self), d + "/self.pbrt:1:1: error: Include cycle: " + d + "/self.pbrt -> " + d +
                                     "/self.pbrt, expected files that do not include themselves");
  EXPECT_EQ(error_loading(dir.file("a.pbrt")), d + "/b.pbrt:2:3: error: Include cycle: " + d + "/a.pbrt -> " + d +
                                                   "/b.pbrt -> " + d + "/a.pbrt, expected files that do not include themselves");
  // The same file twice, not nested, is no cycle.
  dir.write("twice.pbrt", "WorldBegin\nInclude \"part.pbrt\"\nInclude \"part.pbrt\"\n");
  dir.write("part.pbrt", kTri);
  EXPECT_EQ(load_scene(dir.file("twice.pbrt")).shapes.size(), 2u);
}

TEST(Parser, OnlyRegularFilesAreOpened) {
  TempDir dir;
  const std::string fifo = dir.file("fifo.pbrt");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Opening a FIFO would block for ever; the parser must refuse it instead.
  EXPECT_EQ(error_of("Include \"fifo.pbrt\"", dir.path.string()),
            "test.pbrt:1:1: error: cannot open \"" + fifo + "\": it is not a regular file, expected a readable file");
}

TEST(Parser, SingleValuedParametersTakeOneValueAndCountsMustMakeSense) {
  EXPECT_EQ(error_of("Camera \"perspective\" \"float fov\" [45 50]\nWorldBegin"),
            "test.pbrt:1:22: error: \"float fov\" has 2 values, expected 1");
  EXPECT_EQ(error_of("Integrator \"volpath\" \"integer maxdepth\" [-1]\nWorldBegin"),
            "test.pbrt:1:22: error: \"integer maxdepth\" is -1, expected zero or more");
  EXPECT_EQ(error_of("Sampler \"zsobol\" \"integer pixelsamples\" [0]\nWorldBegin"),
            "test.pbrt:1:18: error: \"integer pixelsamples\" is 0, expected a positive count");
  EXPECT_EQ(error_of("WorldBegin\nLightSource \"point\" \"point3 from\" [0 0 0 1 1 1]"),
            "test.pbrt:2:21: error: \"point3 from\" has 6 values, expected 3");
}
