// The scene as plain data: what the parser produces and everything else reads.
//
// Everything here is in render space (= pbrt's world space) unless a field says
// otherwise.  Indices into the Scene's vectors link the parts together; -1
// means "none".  No behaviour lives here: shapes are made traceable by
// scene/accel.h, textures evaluated by scene/texture.h, materials by
// scene/bsdf.h, lights sampled by scene/lights.h.
#pragma once

#include "core/math.h"

#include <memory>
#include <string>
#include <vector>

namespace theia {

// Where a scene element came from, for messages that name file and line.
struct SourceLoc {
  std::string file;
  int line = 0;
  int column = 0;
};

// ---------------------------------------------------------------- textures

enum class TextureKind {
  Constant, ImageMap, Checkerboard, Scale, Mix, Bilerp, Dots, FBm, Wrinkled, Windy, Marble, DirectionMix
};
// pbrt-v4's 2D mappings (TextureMapping2D); Point3D is its 3D PointTransformMapping,
// used by 3D textures (fbm, wrinkled, windy, marble, checkerboard dimension 3).
enum class TextureMappingKind { UV, Spherical, Cylindrical, Planar, Point3D };
enum class WrapMode { Repeat, Black, Clamp, OctahedralSphere };
// pbrt-v4's imagemap "filter" (scene/mipmap.h for Trilinear and EWA).
enum class TextureFilter { Point, Bilinear, Trilinear, EWA };

// pbrt-v4 "uv" mapping: st = (su * u + du, sv * v + dv).
struct UVMapping {
  float su = 1, sv = 1, du = 0, dv = 0;
};

// A loaded image: linear float RGB(A), row 0 at the top, as OpenImageIO reads it.
struct Image {
  std::string filename;
  std::string encoding;       // "sRGB", "linear" or "gamma G"; empty = the file type's default
  bool is_color = false;      // RGB colour (converted to the working space at load), not data (normals, floats)
  int width = 0, height = 0, channels = 0;
  std::vector<float> pixels;  // width * height * channels, linear
  // MIP levels 1, 2, ... (each about half the previous, the last 1x1), built
  // by build_mipmaps (scene/mipmap.h) for images a trilinear or EWA texture reads.
  std::vector<Image> mip;
  SourceLoc loc;              // the parameter that named the file (a load error names it)
};

// One texture node.  Float textures use only the first component of the RGB
// values; `is_float` records which kind the scene declared.
struct Texture {
  std::string name;
  TextureKind kind = TextureKind::Constant;
  bool is_float = false;
  TextureMappingKind mapping_kind = TextureMappingKind::UV;
  UVMapping mapping;           // UV; Planar uses du, dv as its udelta, vdelta
  vec3 planar_s{1, 0, 0}, planar_t{0, 1, 0};  // Planar "v1", "v2" (texture space)
  // Every mapping but UV works on p in texture space: pbrt-v4's textureFromRender,
  // the inverse of the CTM in effect at the Texture directive.
  Transform texture_from_render;
  RGB value{0.0f};             // Constant
  int image = -1;              // ImageMap: index into Scene::images
  WrapMode wrap = WrapMode::Repeat;
  float scale = 1.0f;          // ImageMap "scale"
  bool invert = false;         // ImageMap "invert"
  TextureFilter filter = TextureFilter::Bilinear;  // ImageMap "filter"
  float max_anisotropy = 8.0f;                     // ImageMap "maxanisotropy" (EWA only)
  // Checkerboard (tex1, tex2), Scale (tex, scale), Mix and DirectionMix (tex1, tex2),
  // Dots (inside the dot, outside it: see scene/texture_params.cpp for pbrt-v4's swap)
  int tex1 = -1, tex2 = -1;
  int amount = -1;             // Mix amount (float texture)
  RGB corners[4] = {RGB(0.0f), RGB(1.0f), RGB(0.0f), RGB(1.0f)};  // Bilerp v00, v01, v10, v11
  int octaves = 8;             // FBm, Wrinkled, Marble
  float roughness = 0.5f;      // FBm, Wrinkled, Marble: pbrt-v4's omega
  float marble_scale = 1.0f, variation = 0.2f;  // Marble
  vec3 dir{0, 1, 0};           // DirectionMix: unit, render space
  SourceLoc loc;
};

// ---------------------------------------------------------------- materials

// pbrt-v4's materials.  Texture-valued parameters are indices into
// Scene::textures (float or spectrum as the slot says; constants are
// constant textures); -1 where the material does not use the slot.
enum class MaterialKind {
  Diffuse, Conductor, Dielectric, ThinDielectric, DiffuseTransmission, CoatedDiffuse, CoatedConductor, Mix, Interface,
  Hair  // last, so that checkpoint fingerprints of scenes without hair keep their values
};

struct Material {
  std::string name;
  MaterialKind kind = MaterialKind::Diffuse;
  int reflectance = -1;          // spectrum: diffuse, diffusetransmission, coateddiffuse; conductor's reflectance form
  int transmittance = -1;        // spectrum: diffusetransmission
  float scale = 1.0f;            // diffusetransmission "scale"
  int uroughness = -1, vroughness = -1;  // float: conductor, dielectric, coated interface
  bool remap_roughness = true;
  float eta = 1.5f;              // dielectric, thindielectric, coated interface (at ~550 nm), hair
  int conductor_eta = -1, conductor_k = -1;  // spectrum (RGB): conductor, coatedconductor base
  int conductor_uroughness = -1, conductor_vroughness = -1;  // float: coatedconductor base
  // The conductor's Fresnel reflectance over cos theta (kConductorFresnelTableSize entries, working
  // space) from its spectral eta and k, as pbrt-v4 evaluates it per wavelength
  // (scene/conductor_spectral.h); empty where the per-band eta and k are exact (grey) or textured.
  std::vector<RGB> conductor_fresnel;
  int thickness = -1, g = -1, albedo = -1;  // coated: float, float, spectrum
  int max_depth = 10, n_samples = 1;        // coated
  // hair: sigma_a (spectrum, sRGB bands) wins over reflectance, which wins
  // over eumelanin/pheomelanin (float); -1 where not given.  eta is `eta`.
  int sigma_a = -1, eumelanin = -1, pheomelanin = -1;
  int beta_m = -1, beta_n = -1, hair_alpha = -1;  // float textures (defaults 0.3, 0.3, 2 degrees)
  int mix[2] = {-1, -1};         // Mix: indices into Scene::materials (-1: interface)
  int amount = -1;               // Mix: float texture, probability of mix[1]
  int displacement = -1;         // float texture: bump map
  int normal_map = -1;           // index into Scene::images (linear, tangent-space normals)
  SourceLoc loc;
};

// ---------------------------------------------------------------- shapes

enum class ShapeKind { TriangleMesh, Sphere, Disk, Cylinder, Curve };

// Indexed triangles.  Top-level meshes are stored in render space; meshes of
// an object prototype are stored in the prototype's object space.
struct TriangleMesh {
  std::vector<vec3> p;
  std::vector<vec3> n;              // empty, or one per vertex
  std::vector<vec2> uv;             // empty, or one per vertex
  std::vector<uint32_t> indices;    // 3 per triangle
  // A tessellated bilinearmesh: patch k is triangles [patch_start[k],
  // patch_start[k + 1]).  Empty for other meshes.  pbrt-v4's "power" is per
  // patch, so emission needs to know which triangles make one.
  std::vector<uint32_t> patch_start;
  size_t triangle_count() const { return indices.size() / 3; }
};

// pbrt-v4's "curve" types, traced as Embree's flat (ray-facing), round (a
// real tube, where pbrt-v4 bends the shading normal of a flat ribbon) and
// normal-oriented curves.
enum class CurveType { Flat, Cylinder, Ribbon };

// A "curve" shape's segments, every one converted to a cubic Bezier (degree 2
// elevated, b-splines converted) and baked with the CTM like a mesh: segment k
// is cp[4k .. 4k+3] = (x, y, z, radius), radius = width / 2 interpolated
// linearly along the shape; ribbons carry one normal per control point, n[4k ..].
struct CurveSet {
  CurveType type = CurveType::Flat;
  std::vector<vec4> cp;
  std::vector<vec3> n;              // ribbon only
  size_t segment_count() const { return cp.size() / 4; }
};

struct SphereParams {
  float radius = 1, zmin = -1, zmax = 1, phimax = 360;  // pbrt-v4 semantics (degrees)
};
struct DiskParams {
  float height = 0, radius = 1, innerradius = 0, phimax = 360;
};
// Open at both ends, as pbrt-v4's: the caps are not part of the shape.
struct CylinderParams {
  float radius = 1, zmin = -1, zmax = 1, phimax = 360;
};

struct Shape {
  ShapeKind kind = ShapeKind::TriangleMesh;
  int mesh = -1;                    // TriangleMesh: index into Scene::meshes
  int curves = -1;                  // Curve: index into Scene::curves
  SphereParams sphere;
  DiskParams disk;
  CylinderParams cylinder;
  // Quadrics are intersected in object space; meshes are already baked.
  Transform render_from_object;
  bool reverse_orientation = false; // ReverseOrientation in effect (flips the normal)
  bool transform_swaps_handedness = false;  // of the transform in effect when the shape was declared
  int material = -1;                // index into Scene::materials
  int area_light = -1;              // index into Scene::lights, if emissive
  int alpha = -1;                   // float texture: cut-out where < 1 (issue 3)
  bool holdout = false;             // "bool holdout": blocks rays, contributes neither colour nor alpha
  // MediumInterface: indices into Scene::media, -1 = vacuum.  Only a shape
  // whose two sides differ changes a ray's medium (pbrt-v4's IsMediumTransition).
  int medium_inside = -1, medium_outside = -1;
  bool medium_transition() const { return medium_inside != medium_outside; }
  SourceLoc loc;
};

// ObjectBegin/ObjectEnd: shapes in object space, instanced by ObjectInstance.
struct ObjectPrototype {
  std::string name;
  std::vector<int> shapes;          // indices into Scene::shapes
};
struct Instance {
  int prototype = -1;               // index into Scene::prototypes
  Transform render_from_instance;
};

// ---------------------------------------------------------------- lights

// Goniometric and Projection are pbrt-v4's image-modulated point lights
// (scene/lights.h evaluates their intensity).
enum class LightKind { Area, Point, Infinite, Spot, Distant, Goniometric, Projection };

// pbrt-v4's light semantics, resolved at parse time: L holds the emission
// with "scale" and "power" / "illuminance" already applied (spectra are
// luminance-normalised by scene/spectrum.h, which is pbrt-v4's division by
// SpectrumToPhotometric).  The exceptions need the pixels: an environment
// image's "illuminance" and an image's k_e for "power" (area, goniometric,
// projection); scene/lights.cpp applies them when the LightSet is built.
// The largest radiance or intensity a light may have (after "scale" and
// "power"), and the largest texel an image keeps: beyond, a few bounces and
// the film's sums would overflow float (a larger light is a located error, a
// larger texel is clamped to 0 with a warning).
inline constexpr float kMaxEmission = 1e20f;

struct Light {
  LightKind kind = LightKind::Area;
  // Radiance (area, infinite, distant) or intensity (point, spot, goniometric).
  // For an infinite or projection light with an image: the factor the image
  // is multiplied by.
  RGB L{0.0f};
  bool two_sided = false;           // area
  bool is_virtual = false;          // area: the scene's "bool virtual" parameter
  int shape = -1;                   // area: the emitting shape (index into Scene::shapes)
  vec3 position{0.0f};              // point, spot, goniometric, projection: in render space
  // Spot: unit axis of the cone (from -> to).  Distant: unit direction
  // towards the light (from - to), both in render space.
  vec3 direction{0.0f, 0.0f, 1.0f};
  float cos_falloff_start = 1.0f;   // spot: full intensity inside this cone
  float cos_falloff_end = 1.0f;     // spot: zero outside this one (smoothstep between)
  // Infinite: environment image; area: emission image ("filename", RGB, looked
  // up bilinearly at the hit's uv with v flipped); goniometric: square
  // equal-area map of intensity (loaded as data: pbrt-v4 averages the file's
  // R, G, B into one channel); projection: the RGB image projected.  Index
  // into Scene::images, or -1.  An area or projection light with an image has
  // L = RGB("scale"): the radiance or intensity is L times the texel.
  int image = -1;
  // Area on a triangle mesh with "power": pbrt-v4 makes one light per
  // triangle, each emitting the whole power, so triangle i's radiance is
  // L * triangle_scale[i] (phi / (pi * sides * area_i)).  Empty when every
  // triangle has the same radiance (then L includes the factor).
  std::vector<float> triangle_scale;
  // Area: pbrt-v4 "power" (> 0) if given, already in L / triangle_scale except
  // for an image's mean luminance k_e, which needs the pixels: LightSet divides by it.
  // Goniometric, projection: "power" (> 0) not yet in L; their k_e needs the
  // pixels (and the projection's frustum the image's aspect ratio).
  float power = -1.0f;
  float illuminance = -1.0f;        // infinite with image: pbrt-v4 "illuminance" (> 0), applied by LightSet
  float fov = 90.0f;                // projection: degrees, along the image's shorter axis
  // Infinite: orientation of the environment map.  Goniometric: the CTM times
  // pbrt-v4's y/z swap (the map's pole, light-space +z, is the CTM's +y).
  // Projection: the CTM times pbrt-v4's Scale(1, -1, 1) (the CTM's +y is the
  // image's top); the frustum looks down light-space +z.
  Transform render_from_light;
  SourceLoc loc;
};

// ---------------------------------------------------------------- camera & film

// Lanczos is pbrt-v4's "sinc" filter (LanczosSincFilter).
enum class FilterKind { Box, Triangle, Gaussian, Mitchell, Lanczos };

struct FilterParams {
  FilterKind kind = FilterKind::Gaussian;   // pbrt-v4's default
  vec2 radius{1.5f, 1.5f};
  float sigma = 0.5f;                        // gaussian
  float b = 1.0f / 3.0f, c = 1.0f / 3.0f;    // mitchell "B", "C"
  float tau = 3.0f;                          // lanczos: periods of the window's sinc over the radius
};

// "realistic" is parsed as perspective (scene/README.md).
enum class CameraKind { Perspective, Orthographic, Spherical };
enum class SphericalMapping { EqualArea, Equirectangular };

struct CameraParams {
  CameraKind kind = CameraKind::Perspective;
  Transform render_from_camera;              // camera space: +z forward, pbrt-v4 conventions
  float fov = 90.0f;                         // perspective: degrees, along the shorter image axis
  SphericalMapping mapping = SphericalMapping::EqualArea;  // spherical
  float lens_radius = 0.0f;                  // perspective, orthographic
  float focal_distance = 1e6f;
  float screen_window[4] = {0, 0, 0, 0};     // xmin xmax ymin ymax; all zero = derive from aspect
  bool has_screen_window = false;
};

struct FilmParams {
  int width = 1280, height = 720;
  std::string filename = "pbrt.exr";
};

struct RenderSettings {
  int spp = 16;                              // Sampler "pixelsamples"
  int max_depth = 5;                         // Integrator "maxdepth"
};

// ---------------------------------------------------------------- the scene

// ---------------------------------------------------------------- media

// pbrt-v4's MakeNamedMedium, resolved at parse time (scene/medium_params.h):
// "scale" is applied to sigma_a and sigma_s, "Lescale" to Le.  The grid
// types scale both coefficients by a trilinearly interpolated density (or,
// for an rgbgrid, interpolate the coefficients themselves) and "cloud" by
// pbrt-v4's procedural density (scene/media.h), in the medium's space:
// distances there are measured in that space, as pbrt-v4 measures them.
// "nanovdb" is a uniform grid resampled from the file's sparse one
// (scene/vdb_medium.h).
enum class MediumKind { Homogeneous, UniformGrid, RGBGrid, Cloud, NanoVDB };
struct Medium {
  std::string name;
  MediumKind kind = MediumKind::Homogeneous;
  RGB sigma_a{1.0f}, sigma_s{1.0f};  // per unit length (times density for a grid; rgbgrid: "scale")
  RGB Le{0.0f};                      // emitted radiance (times sigma_a along a path)
  float g = 0.0f;                    // Henyey-Greenstein asymmetry
  // Grids: nx * ny * nz values (x fastest) over the box p0-p1 of medium space.
  int nx = 1, ny = 1, nz = 1;
  std::vector<float> density;
  float max_density = 1.0f;          // the majorant's density (1 for homogeneous)
  std::vector<float> majorants;      // grids and cloud: the majorant grid (scene/media.h)
  vec3 p0{0.0f}, p1{1.0f};
  // rgbgrid: per-voxel sigma_a, sigma_s (empty: 1) and Le (empty: none).
  std::vector<RGB> sigma_a_grid, sigma_s_grid, Le_grid;
  float Le_scale = 1.0f;             // "Lescale" (folded into Le where Le is one colour)
  std::vector<float> Le_scale_grid;  // uniformgrid: "Lescale" given per voxel
  // uniformgrid / nanovdb "temperature" (Kelvin before "temperatureoffset"
  // and "temperaturescale"): blackbody emission, tabulated over temperature.
  std::vector<float> temperature;
  float temperature_offset = 0.0f, temperature_scale = 1.0f;
  std::vector<RGB> blackbody_table;
  float blackbody_t_max = 0.0f;
  // cloud: pbrt-v4's "density", "wispiness", "frequency".
  float cloud_density = 1.0f, wispiness = 1.0f, frequency = 5.0f;
  Transform render_from_medium;
  SourceLoc loc;
};

struct Scene {
  std::string path;                          // the file it was loaded from
  CameraParams camera;
  FilmParams film;
  FilterParams filter;
  RenderSettings settings;

  std::vector<TriangleMesh> meshes;
  std::vector<CurveSet> curves;
  std::vector<Shape> shapes;                 // every shape, top-level and prototype
  std::vector<int> top_level_shapes;         // indices into shapes that are in the world directly
  std::vector<ObjectPrototype> prototypes;
  std::vector<Instance> instances;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Image> images;
  std::vector<Light> lights;
  std::vector<Medium> media;
  int camera_medium = -1;  // pbrt-v4: the outside medium of the MediumInterface current at Camera
  // True when a ray can be in a medium: the camera's, or a shape's interface names one.
  bool has_media() const {
    if (camera_medium >= 0) return true;
    for (const Shape& s : shapes)
      if (s.medium_inside >= 0 || s.medium_outside >= 0) return true;
    return false;
  }
};

}  // namespace theia
