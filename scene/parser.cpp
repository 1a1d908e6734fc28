#include "scene/parser.h"

#include "scene/scene_parser.h"

#include "core/log.h"
#include "scene/camera.h"
#include "scene/camera_params.h"
#include "scene/curve_params.h"
#include "scene/filter.h"
#include "scene/light_params.h"
#include "scene/loop_subdiv.h"
#include "scene/material_params.h"
#include "scene/medium_params.h"
#include "scene/params.h"
#include "scene/ply.h"
#include "scene/spectrum.h"
#include "scene/texture_params.h"
#include "scene/tokenizer.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <filesystem>
#include <map>
#include <optional>
#include <tuple>
#include <unordered_map>

namespace fs = std::filesystem;

namespace theia {

namespace parse_detail {
const char* pushed_name(char kind) {
  return kind == 'a' ? "AttributeBegin" : kind == 't' ? "TransformBegin" : "ObjectBegin";
}

std::string resolve(const std::string& base_dir, const std::string& name) {
  fs::path p(name);
  if (p.is_relative()) p = fs::path(base_dir) / p;
  return p.lexically_normal().string();
}

std::string dir_of(const std::string& path) {
  fs::path dir = fs::path(path).parent_path();
  return dir.empty() ? fs::path(".").string() : dir.string();
}

// The file a path names, one spelling for every way to reach it.
std::string canonical_path(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(path, ec);
  return ec ? fs::absolute(path).lexically_normal().string() : p.string();
}

// ---------------------------------------------------------------- transforms

// A transform every point can go through and come back: finite both ways and
// within a range where float arithmetic on scene coordinates still means
// something.  A singular matrix (Scale 0, a zero Transform) has no inverse.
bool is_usable(const Transform& t) {
  constexpr float kLimit = 1e20f;
  if (!(std::abs(glm::determinant(mat3(t.m))) > 0.0f)) return false;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!(std::abs(t.m[c][r]) < kLimit) || !(std::abs(t.m_inv[c][r]) < kLimit)) return false;
  return true;
}

// ---------------------------------------------------------------- includes

SceneParser::IncludeGuard::IncludeGuard(std::vector<std::string>& c, const std::string& path, const SourceLoc& loc,
                                        std::string_view d)
    : chain(c) {
  std::string file = canonical_path(path);
  if (std::find(chain.begin(), chain.end(), file) != chain.end()) {
    std::string cycle;
    for (auto it = std::find(chain.begin(), chain.end(), file); it != chain.end(); ++it) cycle += *it + " -> ";
    throw_at(loc, "{} cycle: {}{}, expected files that do not include themselves", d, cycle, file);
  }
  if (chain.size() >= kMaxIncludeDepth)
    throw_at(loc, "{} nested {} files deep, expected at most {}", d, chain.size(), kMaxIncludeDepth);
  chain.push_back(std::move(file));
}

void SceneParser::finish(const SourceLoc& end) {
  if (!stack_.empty())
    throw_at(stack_.back().loc, "{} without its end, expected it closed before the end of the scene",
             pushed_name(stack_.back().kind));
  if (!in_world_) throw_at(end, "end of the scene before WorldBegin, expected WorldBegin");
  check_camera_and_filter(end);
}

// The camera and the filter are built as the engine will build them, so an
// unusable one (fov 0, a negative lens radius, a zero filter radius) names
// the directive that made it.
void SceneParser::check_camera_and_filter(const SourceLoc& end) const {
  try {
    make_camera(scene_.camera, scene_.film);
  } catch (const Error& e) {
    throw_at(camera_loc_.value_or(end), "{}", e.what());
  }
  try {
    make_filter(scene_.filter);
  } catch (const Error& e) {
    throw_at(filter_loc_.value_or(end), "{}", e.what());
  }
}

// ---------------------------------------------------------------- options

void SceneParser::camera(const std::string& type, ParamList& params, const SourceLoc& loc) {
  if (!is_usable(gs_.ctm))
    throw_at(loc, "the camera transform is not invertible or not finite (a zero scale, a zero Transform, a huge "
                  "value?), expected an invertible transform");
  camera_loc_ = loc;
  named_coords_["camera"] = gs_.ctm.inverse();
  scene_.camera.render_from_camera = gs_.ctm.inverse();
  scene_.camera_medium = gs_.medium_outside;  // pbrt-v4's CameraTransform-time outside medium
  read_camera(type, params, loc, scene_.camera);
}

void SceneParser::film(const std::string& type, ParamList& params, const SourceLoc& loc) {
  read_film(type, params, loc, scene_.film);
}

void SceneParser::pixel_filter(const std::string& type, ParamList& params, const SourceLoc& loc) {
  filter_loc_ = loc;
  read_pixel_filter(type, params, loc, scene_.filter);
}

// ---------------------------------------------------------------- textures and materials

int SceneParser::constant_texture(RGB v, bool is_float) {
  if (is_float) v = RGB(v.x);
  auto key = std::make_tuple(v.x, v.y, v.z, is_float);
  auto it = constants_.find(key);
  if (it != constants_.end()) return it->second;
  Texture t;
  t.kind = TextureKind::Constant;
  t.is_float = is_float;
  t.value = v;
  scene_.textures.push_back(t);
  return constants_[key] = int(scene_.textures.size()) - 1;
}

int SceneParser::texture_param(const ParamList& p, std::string_view name, bool is_float, RGB def, SpectrumUse use) {
  if (const Param* t = p.find(name, ParamType::Texture)) {
    auto& names = is_float ? float_textures_ : spectrum_textures_;
    auto it = names.find(t->strings[0]);
    if (it == names.end())
      throw_at(t->loc, "unknown {} texture \"{}\", expected a texture declared earlier with Texture",
               is_float ? "float" : "spectrum", t->strings[0]);
    return it->second;
  }
  if (is_float) {
    if (const Param* f = p.find(name, ParamType::Float)) return constant_texture(RGB(float(f->numbers[0])), true);
  } else if (auto c = p.get_spectrum(name, use, def)) {
    return constant_texture(*c, false);
  }
  return constant_texture(def, is_float);
}

int SceneParser::image(const std::string& path, const std::string& encoding, bool is_color, const SourceLoc& loc) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw_at(loc, "image \"{}\" not found, expected an existing file", path);
  std::string abs = fs::absolute(path).lexically_normal().string();
  auto key = std::make_tuple(abs, encoding, is_color);
  auto it = images_.find(key);
  if (it != images_.end()) return it->second;
  Image img;
  img.filename = abs;
  img.encoding = encoding;
  img.is_color = is_color;
  img.loc = loc;
  scene_.images.push_back(std::move(img));
  return images_[key] = int(scene_.images.size()) - 1;
}

void SceneParser::texture(const std::string& name, const std::string& type, const std::string& cls,
                          ParamList& params, const SourceLoc& loc, const std::string& base_dir) {
  if (type != "float" && type != "spectrum")
    throw_at(loc, "texture type \"{}\", expected \"float\" or \"spectrum\"", type);
  bool is_float = type == "float";
  auto& names = is_float ? float_textures_ : spectrum_textures_;
  if (names.count(name)) throw_at(loc, "texture \"{}\" redefined, expected a new name", name);
  TextureLookups lookups;
  lookups.texture = [this](const ParamList& p, std::string_view n, bool f, RGB def, SpectrumUse use) {
    return texture_param(p, n, f, def, use);
  };
  lookups.image = [&](const std::string& file, const std::string& encoding, bool is_color, const SourceLoc& l) {
    return image(resolve(base_dir, file), encoding, is_color, l);
  };
  scene_.textures.push_back(parse_texture(name, is_float, cls, params, gs_.ctm, loc, lookups));
  names[name] = int(scene_.textures.size()) - 1;
}

int SceneParser::make_material(const std::string& type, const std::string& name, ParamList& params,
                               const SourceLoc& loc, const std::string& base_dir) {
  MaterialLookups lookups;
  lookups.texture = [this](const ParamList& p, std::string_view n, bool is_float, RGB def, SpectrumUse use) {
    return texture_param(p, n, is_float, def, use);
  };
  lookups.image = [&](const std::string& file, const std::string& encoding, const SourceLoc& l) {
    return image(resolve(base_dir, file), encoding, /*is_color=*/false, l);  // normal maps: data
  };
  lookups.named_material = [this](const std::string& n, const SourceLoc& l) {
    auto it = named_materials_.find(n);
    if (it == named_materials_.end())
      throw_at(l, "unknown named material \"{}\", expected a name defined by MakeNamedMaterial", n);
    return it->second;
  };
  Material m = parse_material(type, params, loc, lookups);
  m.name = name;
  scene_.materials.push_back(std::move(m));
  return int(scene_.materials.size()) - 1;
}

int SceneParser::default_material() {
  if (default_material_ < 0) {
    Material m;
    m.reflectance = constant_texture(RGB(0.5f), false);
    scene_.materials.push_back(std::move(m));
    default_material_ = int(scene_.materials.size()) - 1;
  }
  return default_material_;
}

// ---------------------------------------------------------------- lights

// Emission beyond kMaxEmission (3e38 in a scene) would overflow on its way to the film.
static void check_emission(const RGB& L, const SourceLoc& loc) {
  float m = std::max({std::abs(L.x), std::abs(L.y), std::abs(L.z)});
  if (!(m <= kMaxEmission))
    throw_at(loc, "emission {:g} (after \"scale\" and \"power\"), expected at most {:g}", double(m),
             double(kMaxEmission));
}

void SceneParser::area_light_source(const std::string& type, ParamList& params, const SourceLoc& loc,
                                    const std::string& base_dir) {
  gs_.area_light = false;
  if (type != "diffuse") {
    warn_at(loc, "area light \"{}\" is not supported; ignored", type);
    params.mark_all_used();
    return;
  }
  std::optional<RGB> L = params.get_spectrum("L", SpectrumUse::Illuminant, RGB(1.0f));
  float scale = params.get_float("scale", 1.0f);
  AreaLightParams a;
  if (const Param* f = params.find("filename", ParamType::String)) {
    if (L) throw_at(loc, "diffuse area light with both \"L\" and \"filename\", expected one of them");
    a.image = image(resolve(base_dir, f->strings[0]), "", true, f->loc);
    a.L = RGB(scale);  // the texel is the radiance (pbrt-v4's RGBIlluminantSpectrum)
  } else {
    a.L = L.value_or(RGB(1.0f)) * scale;
  }
  float power = params.get_float("power", -1.0f);
  a.power = power > 0.0f ? power : -1.0f;
  check_emission(a.L, loc);
  a.two_sided = params.get_bool("twosided", false);
  a.is_virtual = params.get_bool("virtual", false);
  gs_.area_light = true;
  gs_.area = a;
}

void SceneParser::light_source(const std::string& type, ParamList& params, const SourceLoc& loc,
                               const std::string& base_dir) {
  // Each branch follows pbrt-v4's Light::Create for the type: the spectrum is
  // luminance-normalised (scene/spectrum.h), then "scale", then "power" or
  // "illuminance" divided by what a unit emitter of that shape gives (k_e).
  Light l;
  l.loc = loc;
  float scale = params.get_float("scale", 1.0f);
  auto spectrum = [&](const char* name) {
    return params.get_spectrum(name, SpectrumUse::Illuminant, RGB(1.0f)).value_or(RGB(1.0f));
  };
  auto positive = [&](const char* name) {
    float v = params.get_float(name, -1.0f);
    return v > 0.0f ? v : -1.0f;
  };
  if (type == "point") {
    l.kind = LightKind::Point;
    if (float phi = positive("power"); phi > 0.0f) scale *= phi / (4.0f * kPi);
    l.L = spectrum("I") * scale;
    l.position = gs_.ctm.point(params.get_point3("from", vec3(0.0f)));
  } else if (type == "spot") {
    l.kind = LightKind::Spot;
    float cone = params.get_float("coneangle", 30.0f);
    float delta = params.get_float("conedeltaangle", 5.0f);
    vec3 from = params.get_point3("from", vec3(0.0f)), to = params.get_point3("to", vec3(0.0f, 0.0f, 1.0f));
    vec3 axis = gs_.ctm.vector(to - from);
    if (!(glm::length(axis) > 0.0f)) throw_at(loc, "spot light with \"from\" == \"to\", expected a direction");
    l.position = gs_.ctm.point(from);
    l.direction = glm::normalize(axis);
    l.cos_falloff_end = std::cos(radians(cone));
    l.cos_falloff_start = std::cos(radians(cone - delta));
    if (float phi = positive("power"); phi > 0.0f)
      scale *= phi / (2.0f * kPi * ((1.0f - l.cos_falloff_start) + (l.cos_falloff_start - l.cos_falloff_end) / 2.0f));
    l.L = spectrum("I") * scale;
  } else if (type == "distant") {
    l.kind = LightKind::Distant;
    vec3 from = params.get_point3("from", vec3(0.0f)), to = params.get_point3("to", vec3(0.0f, 0.0f, 1.0f));
    vec3 w = gs_.ctm.vector(from - to);
    if (!(glm::length(w) > 0.0f)) throw_at(loc, "distant light with \"from\" == \"to\", expected a direction");
    l.direction = glm::normalize(w);
    // pbrt-v4: illuminance on a patch facing the light, so k_e = 1.
    if (float e = positive("illuminance"); e > 0.0f) scale *= e;
    l.L = spectrum("L") * scale;
  } else if (type == "infinite") {
    l.kind = LightKind::Infinite;
    l.render_from_light = gs_.ctm;
    std::optional<RGB> L = params.get_spectrum("L", SpectrumUse::Illuminant, RGB(1.0f));
    const Param* f = params.find("filename", ParamType::String);
    if (L && f) throw_at(loc, "infinite light with both \"L\" and \"filename\", expected one of them");
    float e = positive("illuminance");
    if (f) {
      l.image = image(resolve(base_dir, f->strings[0]), "", true, f->loc);
      l.L = RGB(scale);
      l.illuminance = e;  // needs the pixels: applied by LightSet
    } else {
      // A uniform sky of radiance L gives an upward patch illuminance pi L.
      if (e > 0.0f) scale *= e / kPi;
      l.L = L.value_or(RGB(1.0f)) * scale;
    }
    if (const Param* p = params.find("portal", ParamType::Point3))
      warn_at(p->loc, "infinite light portals are not supported; \"portal\" ignored");
  } else if (type == "goniometric" || type == "projection") {
    // Point lights modulated by an image; k_e for "power" needs the pixels (LightSet).
    const Param* f = params.find("filename", ParamType::String);
    if (!f) throw_at(loc, "{} light without \"string filename\", expected an image", type);
    bool gonio = type == "goniometric";
    // pbrt-v4 averages a goniometric image's stored R, G, B (data, not a colour).
    l.image = image(resolve(base_dir, f->strings[0]), "", !gonio, f->loc);
    l.position = gs_.ctm.point(vec3(0.0f));
    l.power = positive("power");
    if (gonio) {
      l.kind = LightKind::Goniometric;
      l.L = spectrum("I") * scale;
      l.render_from_light = gs_.ctm * Transform(mat4(1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 1));  // y <-> z
    } else {
      l.kind = LightKind::Projection;
      l.L = RGB(scale);  // the texel is the intensity (pbrt-v4's RGBIlluminantSpectrum)
      l.fov = params.get_float("fov", 90.0f);
      if (!(l.fov > 0.0f && l.fov < 180.0f)) throw_at(loc, "projection \"fov\" {}, expected (0, 180) degrees", l.fov);
      l.render_from_light = gs_.ctm * Transform(glm::scale(mat4(1.0f), vec3(1, -1, 1)));
    }
  } else {
    warn_at(loc, "light \"{}\" is not supported; ignored", type);
    params.mark_all_used();
    return;
  }
  check_emission(l.L, loc);
  scene_.lights.push_back(l);
}

// ---------------------------------------------------------------- shapes

void SceneParser::bake(TriangleMesh& m) const {
  const Transform& t = gs_.ctm;
  if (!t.is_identity()) {
    for (vec3& p : m.p) p = t.point(p);
    for (vec3& n : m.n) n = t.normal(n);
  }
  if (gs_.reverse_orientation)
    for (vec3& n : m.n) n = -n;
}

// "" is vacuum; a name must be defined before it is used (pbrt-v4 resolves
// names when the scene is built, so it also takes later definitions).
int SceneParser::medium_index(const std::string& name, const SourceLoc& loc) const {
  if (name.empty()) return -1;
  auto it = named_media_.find(name);
  if (it == named_media_.end())
    throw_at(loc, "unknown medium \"{}\", expected a medium defined earlier with MakeNamedMedium (or \"\")", name);
  return it->second;
}

void SceneParser::add_shape(Shape s, const ParamList& params) {
  s.reverse_orientation = gs_.reverse_orientation;
  s.transform_swaps_handedness = gs_.ctm.swaps_handedness();
  s.material = gs_.material >= 0 ? gs_.material : default_material();
  s.holdout = params.get_bool("holdout", false);
  s.medium_inside = gs_.medium_inside;
  s.medium_outside = gs_.medium_outside;
  if (params.find_any("alpha", {ParamType::Float, ParamType::Texture})) {
    s.alpha = texture_param(params, "alpha", true, RGB(1.0f), SpectrumUse::Unbounded);
    const Texture& t = scene_.textures[size_t(s.alpha)];
    if (t.kind == TextureKind::Constant && t.value.x >= 1.0f) s.alpha = -1;  // opaque: no test to pay for
  }
  int index = int(scene_.shapes.size());
  if (gs_.area_light) {
    if (object_ >= 0) {
      warn_at(s.loc, "area lights inside ObjectBegin are not supported (pbrt-v4 neither); emission ignored");
    } else {
      s.area_light = int(scene_.lights.size());
      scene_.lights.push_back(make_area_light(scene_, gs_.area, s, index));
    }
  }
  scene_.shapes.push_back(std::move(s));
  if (object_ >= 0) scene_.prototypes[size_t(object_)].shapes.push_back(index);
  else scene_.top_level_shapes.push_back(index);
}

bool SceneParser::triangle_mesh(const ParamList& params, const SourceLoc& loc, TriangleMesh* out) {
  if (!mesh_from_params(params, loc, "trianglemesh", 3, out)) return false;
  bake(*out);
  return true;
}

bool SceneParser::bilinear_mesh(const ParamList& params, const SourceLoc& loc, TriangleMesh* out) {
  TriangleMesh patches;
  if (!mesh_from_params(params, loc, "bilinearmesh", 4, &patches)) return false;
  bake(patches);  // bilinear interpolation commutes with the affine CTM
  *out = tessellate_bilinear_patches(patches, gs_.reverse_orientation != gs_.ctm.swaps_handedness());
  return true;
}

void SceneParser::shape(const std::string& type, ParamList& params, const SourceLoc& loc, const std::string& base_dir) {
  if (!is_usable(gs_.ctm)) {
    warn_at(loc, "shape \"{}\" under a transform that is not invertible or not finite (a zero scale?); shape ignored",
            type);
    params.mark_all_used();
    return;
  }
  Shape s;
  s.loc = loc;
  TriangleMesh mesh;
  bool is_mesh = false;
  if (type == "trianglemesh") {
    is_mesh = triangle_mesh(params, loc, &mesh);
    if (!is_mesh) return;
  } else if (type == "bilinearmesh") {
    is_mesh = bilinear_mesh(params, loc, &mesh);
    if (!is_mesh) return;
  } else if (type == "plymesh") {
    const Param* f = params.find("filename", ParamType::String);
    if (!f) throw_at(loc, "plymesh without \"string filename\", expected a PLY file");
    std::string path = resolve(base_dir, f->strings[0]);
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) throw_at(loc, "PLY file \"{}\" not found, expected an existing file", path);
    mesh = read_ply(path);
    if (mesh.indices.empty()) {
      warn_at(loc, "PLY file \"{}\" has no triangles; shape ignored", path);
      return;
    }
    bake(mesh);
    is_mesh = true;
  } else if (type == "sphere") {
    s.kind = ShapeKind::Sphere;
    float r = params.get_float("radius", 1.0f);
    s.sphere = {r, params.get_float("zmin", -r), params.get_float("zmax", r), params.get_float("phimax", 360.0f)};
    s.render_from_object = gs_.ctm;
  } else if (type == "loopsubdiv") {
    is_mesh = loop_subdiv_from_params(params, loc, &mesh);
    if (!is_mesh) return;
    bake(mesh);
  } else if (type == "cylinder") {
    s.kind = ShapeKind::Cylinder;
    s.cylinder = {params.get_float("radius", 1.0f), params.get_float("zmin", -1.0f), params.get_float("zmax", 1.0f),
                  params.get_float("phimax", 360.0f)};
    s.render_from_object = gs_.ctm;
  } else if (type == "disk") {
    s.kind = ShapeKind::Disk;
    s.disk = {params.get_float("height", 0.0f), params.get_float("radius", 1.0f), params.get_float("innerradius", 0.0f),
              params.get_float("phimax", 360.0f)};
    s.render_from_object = gs_.ctm;
  } else if (type == "curve") {
    CurveSet c = curves_from_params(params, loc, gs_.ctm);
    s.kind = ShapeKind::Curve;
    s.curves = int(scene_.curves.size());
    scene_.curves.push_back(std::move(c));
    // pbrt-v4 cannot sample curve area lights either: the curve is added
    // without the emission.
    if (gs_.area_light) {
      if (!warned_curve_light_) warn_at(loc, "area lights on curves are not supported (pbrt-v4 neither); emission ignored");
      warned_curve_light_ = true;
      gs_.area_light = false;
      add_shape(std::move(s), params);
      gs_.area_light = true;
      return;
    }
  } else {
    warn_at(loc, "shape \"{}\" is not supported; ignored", type);
    params.mark_all_used();
    return;
  }
  if (is_mesh) {
    s.kind = ShapeKind::TriangleMesh;
    s.mesh = int(scene_.meshes.size());
    scene_.meshes.push_back(std::move(mesh));
  }
  add_shape(std::move(s), params);
}

Scene run(Tokenizer& tok, const std::string& base_dir, const std::string& scene_path) {
  Scene scene;
  scene.path = scene_path;
  SceneParser parser(scene);
  parser.parse(tok, base_dir);
  Token end = tok.peek();
  parser.finish(tok.loc(end));
  return scene;
}

}  // namespace parse_detail

using parse_detail::dir_of;
using parse_detail::run;

Scene load_scene(const std::string& path) {
  auto tok = Tokenizer::from_file(path, nullptr);
  return run(*tok, dir_of(path), fs::absolute(path).lexically_normal().string());
}

Scene parse_scene_string(const std::string& text, const std::string& name, const std::string& base_dir) {
  Tokenizer tok(text, name);
  return run(tok, base_dir, name);
}

}  // namespace theia

