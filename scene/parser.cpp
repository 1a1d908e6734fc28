#include "scene/parser.h"

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

namespace {

using SpectrumUse = ParamList::SpectrumUse;

struct GraphicsState {
  Transform ctm;
  bool reverse_orientation = false;
  bool end_time_only = false;  // ActiveTransform EndTime: edits go to the end transform, which theia drops
  int material = -1;           // -1: the default diffuse 0.5
  bool area_light = false;
  AreaLightParams area;        // resolved per shape by make_area_light
  int medium_inside = -1, medium_outside = -1;  // MediumInterface: Scene::media indices, -1 vacuum
  ParamList shape_attrs, light_attrs, material_attrs, texture_attrs;
};

struct Pushed {
  char kind;  // 'a' AttributeBegin, 't' TransformBegin, 'o' ObjectBegin
  GraphicsState state;
  SourceLoc loc;
};

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

class SceneParser {
 public:
  explicit SceneParser(Scene& scene) : scene_(scene) {
    named_coords_["world"] = Transform();
    if (!scene.path.empty()) includes_.push_back(canonical_path(scene.path));
  }

  void parse(Tokenizer& tok, const std::string& base_dir);
  void finish(const SourceLoc& end);

 private:
  // ---- reading directive arguments
  float number(Tokenizer& tok, std::string_view directive);
  void numbers(Tokenizer& tok, std::string_view directive, float* out, int n, bool brackets);
  std::string string_arg(Tokenizer& tok, std::string_view directive);
  void need_world(const SourceLoc& loc, std::string_view d) const;
  void need_options(const SourceLoc& loc, std::string_view d) const;

  void apply(const Transform& t) {
    if (!gs_.end_time_only) gs_.ctm = gs_.ctm * t;
  }
  void set_ctm(const Transform& t) {
    if (!gs_.end_time_only) gs_.ctm = t;
  }
  void warn_motion(const SourceLoc& loc);

  // ---- scene content
  void camera(const std::string& type, ParamList& params, const SourceLoc& loc);
  void film(const std::string& type, ParamList& params, const SourceLoc& loc);
  void pixel_filter(const std::string& type, ParamList& params, const SourceLoc& loc);
  void shape(const std::string& type, ParamList& params, const SourceLoc& loc, const std::string& base_dir);
  void light_source(const std::string& type, ParamList& params, const SourceLoc& loc, const std::string& base_dir);
  void area_light_source(const std::string& type, ParamList& params, const SourceLoc& loc,
                         const std::string& base_dir);
  int make_material(const std::string& type, const std::string& name, ParamList& params, const SourceLoc& loc,
                    const std::string& base_dir);
  void texture(const std::string& name, const std::string& type, const std::string& cls, ParamList& params,
               const SourceLoc& loc, const std::string& base_dir);

  int constant_texture(RGB v, bool is_float);
  int texture_param(const ParamList& p, std::string_view name, bool is_float, RGB def, SpectrumUse use);
  int image(const std::string& path, const std::string& encoding, bool is_color, const SourceLoc& loc);
  int default_material();
  void bake(TriangleMesh& m) const;
  void add_shape(Shape s, const ParamList& params);
  bool triangle_mesh(const ParamList& params, const SourceLoc& loc, TriangleMesh* out);
  bool bilinear_mesh(const ParamList& params, const SourceLoc& loc, TriangleMesh* out);

  // The files being parsed, outermost first: an Include of one of them
  // would recurse until the stack overflows.
  struct IncludeGuard {
    std::vector<std::string>& chain;
    IncludeGuard(std::vector<std::string>& c, const std::string& path, const SourceLoc& loc, std::string_view d);
    ~IncludeGuard() { chain.pop_back(); }
  };
  static constexpr size_t kMaxIncludeDepth = 64;
  std::vector<std::string> includes_;

  Scene& scene_;
  GraphicsState gs_;
  std::vector<Pushed> stack_;
  bool in_world_ = false;
  int object_ = -1;  // prototype being defined
  bool warned_motion_ = false, warned_transform_begin_ = false;
  std::unordered_map<std::string, Transform> named_coords_;
  std::unordered_map<std::string, int> named_materials_, float_textures_, spectrum_textures_, objects_, named_media_;
  int medium_index(const std::string& name, const SourceLoc& loc) const;
  std::map<std::tuple<float, float, float, bool>, int> constants_;
  std::map<std::tuple<std::string, std::string, bool>, int> images_;
  int default_material_ = -1;
  bool warned_curve_light_ = false;
  // Where the camera and the filter were declared: their checks need the
  // whole options block (the film's size), so they run at the end.
  std::optional<SourceLoc> camera_loc_, filter_loc_;
  void check_camera_and_filter(const SourceLoc& end) const;
};

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

// ---------------------------------------------------------------- arguments

float SceneParser::number(Tokenizer& tok, std::string_view directive) {
  Token t = tok.next();
  double v;
  if (t.kind == Token::Bare && parse_number(t.text, &v)) {
    // Transforms multiply into every point of the scene: one NaN, or a value
    // past float's range, poisons the whole image (or crashes Embree).
    if (!std::isfinite(float(v)))
      throw_at(tok.loc(t), "{} \"{}\" for {}, expected a finite number", std::isfinite(v) ? "out-of-range number" : "non-finite number", t.text, directive);
    return float(v);
  }
  if (t.kind == Token::Bare) throw_at(tok.loc(t), "bad number \"{}\" for {}, expected a number", t.text, directive);
  throw_at(tok.loc(t), "{} for {}, expected a number", Tokenizer::describe(t), directive);
}

void SceneParser::numbers(Tokenizer& tok, std::string_view directive, float* out, int n, bool brackets) {
  bool open = brackets && tok.peek().kind == Token::LBracket;
  if (open) tok.next();
  for (int i = 0; i < n; ++i) {
    if (open && tok.peek().kind == Token::RBracket)
      throw_at(tok.loc(tok.peek()), "']' after {} values for {}, expected {}", i, directive, n);
    if (open && tok.peek().kind == Token::End)
      throw_at(tok.loc(tok.peek()), "unexpected end of file inside the list of {}, expected ']'", directive);
    out[i] = number(tok, directive);
  }
  if (open) {
    Token t = tok.next();
    if (t.kind != Token::RBracket)
      throw_at(tok.loc(t), "{} after {} values for {}, expected ']'", Tokenizer::describe(t), n, directive);
  }
}

std::string SceneParser::string_arg(Tokenizer& tok, std::string_view directive) {
  Token t = tok.next();
  if (t.kind != Token::String)
    throw_at(tok.loc(t), "{} after {}, expected a quoted string", Tokenizer::describe(t), directive);
  return tok.string_value(t);
}

void SceneParser::need_world(const SourceLoc& loc, std::string_view d) const {
  if (!in_world_) throw_at(loc, "{} before WorldBegin, expected it after WorldBegin", d);
}
void SceneParser::need_options(const SourceLoc& loc, std::string_view d) const {
  if (in_world_) throw_at(loc, "{} after WorldBegin, expected it before WorldBegin", d);
}

void SceneParser::warn_motion(const SourceLoc& loc) {
  if (warned_motion_) return;
  warned_motion_ = true;
  warn_at(loc, "motion blur is not supported; only the start transform is used");
}

// ---------------------------------------------------------------- directives

void SceneParser::parse(Tokenizer& tok, const std::string& base_dir) {
  while (true) {
    Token t = tok.next();
    if (t.kind == Token::End) return;
    SourceLoc loc = tok.loc(t);
    if (t.kind != Token::Bare) throw_at(loc, "unexpected {}, expected a directive", Tokenizer::describe(t));
    std::string_view d = t.text;

    if (d == "Shape") {
      need_world(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      params.add_defaults(gs_.shape_attrs);
      shape(type, params, loc, base_dir);
      params.report_unused();
    } else if (d == "AttributeBegin" || d == "TransformBegin") {
      if (d == "AttributeBegin") need_world(loc, d);
      else if (!warned_transform_begin_) {
        warned_transform_begin_ = true;
        warn_at(loc, "TransformBegin/TransformEnd are deprecated; use AttributeBegin/AttributeEnd");
      }
      stack_.push_back({d == "AttributeBegin" ? 'a' : 't', gs_, loc});
    } else if (d == "AttributeEnd" || d == "TransformEnd") {
      if (d == "AttributeEnd") need_world(loc, d);
      char kind = d == "AttributeEnd" ? 'a' : 't';
      if (stack_.empty()) throw_at(loc, "{} without {}", d, pushed_name(kind));
      if (stack_.back().kind != kind)
        throw_at(loc, "{} while {} at {} is open, expected its end first", d, pushed_name(stack_.back().kind),
                 format_loc(stack_.back().loc));
      if (kind == 'a') {
        gs_ = std::move(stack_.back().state);
      } else {
        gs_.ctm = stack_.back().state.ctm;
      }
      stack_.pop_back();
    } else if (d == "Transform" || d == "ConcatTransform") {
      float m[16];
      numbers(tok, d, m, 16, true);
      // The 16 values are pbrt's transposed (column-major) matrix, which is GLM's layout.
      Transform tr(glm::make_mat4(m));
      if (d == "Transform") set_ctm(tr);
      else apply(tr);
    } else if (d == "Translate") {
      float v[3];
      numbers(tok, d, v, 3, false);
      apply(Transform(glm::translate(mat4(1.0f), vec3(v[0], v[1], v[2])), glm::translate(mat4(1.0f), -vec3(v[0], v[1], v[2]))));
    } else if (d == "Scale") {
      float v[3];
      numbers(tok, d, v, 3, false);
      apply(Transform(glm::scale(mat4(1.0f), vec3(v[0], v[1], v[2]))));
    } else if (d == "Rotate") {
      float v[4];
      numbers(tok, d, v, 4, false);
      vec3 axis(v[1], v[2], v[3]);
      if (glm::length(axis) == 0.0f) throw_at(loc, "Rotate about a zero axis, expected a non-zero axis");
      mat4 r = glm::rotate(mat4(1.0f), radians(v[0]), glm::normalize(axis));
      apply(Transform(r, glm::transpose(r)));
    } else if (d == "LookAt") {
      float v[9];
      numbers(tok, d, v, 9, false);
      vec3 eye(v[0], v[1], v[2]), look(v[3], v[4], v[5]), up(v[6], v[7], v[8]);
      vec3 dir = look - eye;
      if (glm::length(dir) == 0.0f) throw_at(loc, "LookAt with the eye at the look-at point, expected distinct points");
      if (!(glm::length(up) > 0.0f)) throw_at(loc, "LookAt with a zero up vector, expected a non-zero up vector");
      dir = glm::normalize(dir);
      vec3 right = glm::cross(glm::normalize(up), dir);
      if (!(glm::length(right) > 0.0f)) throw_at(loc, "LookAt with the up vector along the view direction, expected them not parallel");
      right = glm::normalize(right);
      vec3 new_up = glm::cross(dir, right);
      // pbrt-v4's left-handed camera frame: x right, y up, z forward.
      mat4 world_from_camera(vec4(right, 0), vec4(new_up, 0), vec4(dir, 0), vec4(eye, 1));
      apply(Transform(world_from_camera).inverse());
    } else if (d == "Identity") {
      set_ctm(Transform());
    } else if (d == "CoordinateSystem") {
      named_coords_[string_arg(tok, d)] = gs_.ctm;
    } else if (d == "CoordSysTransform") {
      std::string name = string_arg(tok, d);
      auto it = named_coords_.find(name);
      if (it == named_coords_.end()) warn_at(loc, "unknown coordinate system \"{}\"; CoordSysTransform ignored", name);
      else set_ctm(it->second);
    } else if (d == "NamedMaterial") {
      need_world(loc, d);
      std::string name = string_arg(tok, d);
      auto it = named_materials_.find(name);
      if (it == named_materials_.end())
        throw_at(loc, "unknown named material \"{}\", expected a name defined by MakeNamedMaterial", name);
      gs_.material = it->second;
    } else if (d == "MakeNamedMaterial") {
      need_world(loc, d);
      std::string name = string_arg(tok, d);
      ParamList params = parse_params(tok);
      params.add_defaults(gs_.material_attrs);
      if (named_materials_.count(name)) throw_at(loc, "named material \"{}\" redefined, expected a new name", name);
      const Param* type = params.find("type", ParamType::String);
      if (!type) throw_at(loc, "MakeNamedMaterial \"{}\" without \"string type\", expected the material type", name);
      named_materials_[name] = make_material(type->strings[0], name, params, loc, base_dir);
      params.report_unused();
    } else if (d == "Material") {
      need_world(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      params.add_defaults(gs_.material_attrs);
      gs_.material = make_material(type, "", params, loc, base_dir);
      params.report_unused();
    } else if (d == "Texture") {
      need_world(loc, d);
      std::string name = string_arg(tok, d);
      std::string type = string_arg(tok, d);
      std::string cls = string_arg(tok, d);
      ParamList params = parse_params(tok);
      params.add_defaults(gs_.texture_attrs);
      texture(name, type, cls, params, loc, base_dir);
      params.report_unused();
    } else if (d == "AreaLightSource") {
      need_world(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      params.add_defaults(gs_.light_attrs);
      area_light_source(type, params, loc, base_dir);
      params.report_unused();
    } else if (d == "LightSource") {
      need_world(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      params.add_defaults(gs_.light_attrs);
      light_source(type, params, loc, base_dir);
      params.report_unused();
    } else if (d == "ReverseOrientation") {
      need_world(loc, d);
      gs_.reverse_orientation = !gs_.reverse_orientation;
    } else if (d == "ObjectBegin") {
      need_world(loc, d);
      std::string name = string_arg(tok, d);
      if (object_ >= 0)
        throw_at(loc, "ObjectBegin \"{}\" inside the definition of \"{}\", expected ObjectEnd first", name,
                 scene_.prototypes[size_t(object_)].name);
      if (objects_.count(name)) throw_at(loc, "object \"{}\" redefined, expected a new name", name);
      stack_.push_back({'o', gs_, loc});
      object_ = int(scene_.prototypes.size());
      objects_[name] = object_;
      scene_.prototypes.push_back({name, {}});
    } else if (d == "ObjectEnd") {
      need_world(loc, d);
      if (object_ < 0) throw_at(loc, "ObjectEnd without ObjectBegin");
      if (stack_.back().kind != 'o')
        throw_at(loc, "ObjectEnd while {} at {} is open, expected its end first", pushed_name(stack_.back().kind),
                 format_loc(stack_.back().loc));
      gs_ = std::move(stack_.back().state);
      stack_.pop_back();
      object_ = -1;
    } else if (d == "ObjectInstance") {
      need_world(loc, d);
      std::string name = string_arg(tok, d);
      if (object_ >= 0) throw_at(loc, "ObjectInstance inside an object definition, expected ObjectEnd first");
      auto it = objects_.find(name);
      if (it == objects_.end()) throw_at(loc, "unknown object \"{}\", expected a name defined by ObjectBegin", name);
      if (!is_usable(gs_.ctm)) warn_at(loc, "ObjectInstance \"{}\" under a transform that is not invertible or not finite; instance ignored", name);
      else scene_.instances.push_back({it->second, gs_.ctm});
    } else if (d == "Include" || d == "Import") {
      if (d == "Import") need_world(loc, d);
      std::string path = resolve(base_dir, string_arg(tok, d));
      IncludeGuard guard(includes_, path, loc, d);
      auto sub = Tokenizer::from_file(path, &loc);
      std::string dir = dir_of(path);
      if (d == "Include") {
        parse(*sub, dir);
      } else {
        // Import may not change the importer's graphics state (pbrt-v4 parses it on its own copy).
        GraphicsState saved = gs_;
        size_t depth = stack_.size();
        parse(*sub, dir);
        if (stack_.size() != depth)
          throw_at(stack_.back().loc, "{} without its end in the imported file, expected it closed there",
                   pushed_name(stack_.back().kind));
        gs_ = std::move(saved);
      }
    } else if (d == "WorldBegin") {
      need_options(loc, d);
      in_world_ = true;
      gs_.ctm = Transform();
      gs_.end_time_only = false;
      named_coords_["world"] = gs_.ctm;
    } else if (d == "Camera") {
      need_options(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      camera(type, params, loc);
      params.report_unused();
    } else if (d == "Film") {
      need_options(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      film(type, params, loc);
      params.report_unused();
    } else if (d == "PixelFilter") {
      need_options(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      pixel_filter(type, params, loc);
      params.report_unused();
    } else if (d == "Sampler" || d == "Integrator" || d == "Accelerator") {
      need_options(loc, d);
      std::string type = string_arg(tok, d);
      ParamList params = parse_params(tok);
      if (d == "Sampler") {
        scene_.settings.spp = params.get_int("pixelsamples", scene_.settings.spp);
        if (scene_.settings.spp <= 0)
          throw_at(params.find("pixelsamples", ParamType::Integer)->loc, "\"integer pixelsamples\" is {}, expected a "
                   "positive count", scene_.settings.spp);
        log_info("{}: note: theia uses its own sampler; of Sampler \"{}\" only pixelsamples is used", format_loc(loc), type);
      } else if (d == "Integrator") {
        scene_.settings.max_depth = params.get_int("maxdepth", scene_.settings.max_depth);
        if (scene_.settings.max_depth < 0)
          throw_at(params.find("maxdepth", ParamType::Integer)->loc, "\"integer maxdepth\" is {}, expected zero or more",
                   scene_.settings.max_depth);
        log_info("{}: note: theia has its own integrator; of Integrator \"{}\" only maxdepth is used", format_loc(loc), type);
      } else {
        log_info("{}: note: Accelerator \"{}\" ignored; theia uses Embree", format_loc(loc), type);
        params.mark_all_used();
      }
      params.report_unused();
    } else if (d == "ColorSpace") {
      std::string name = string_arg(tok, d);
      if (name != "srgb") warn_at(loc, "color space \"{}\" is not supported; theia renders in linear sRGB", name);
    } else if (d == "Option") {
      ParamList params = parse_params(tok);
      if (params.params.size() != 1) throw_at(loc, "Option with {} parameters, expected one", params.params.size());
      warn_at(loc, "Option {} is ignored by theia", params.params[0].label());
    } else if (d == "Attribute") {
      std::string target = string_arg(tok, d);
      ParamList params = parse_params(tok);
      ParamList* attrs = target == "shape"      ? &gs_.shape_attrs
                         : target == "light"    ? &gs_.light_attrs
                         : target == "material" ? &gs_.material_attrs
                         : target == "texture"  ? &gs_.texture_attrs
                                                : nullptr;
      if (target == "medium") {
        warn_at(loc, "participating media are not supported yet; Attribute \"medium\" ignored");
      } else if (!attrs) {
        throw_at(loc, "unknown attribute target \"{}\", expected \"shape\", \"light\", \"material\", \"medium\" or \"texture\"", target);
      } else {
        for (Param& p : params.params) {
          std::erase_if(attrs->params, [&](const Param& q) { return q.name == p.name; });
          attrs->params.push_back(std::move(p));
        }
      }
    } else if (d == "ActiveTransform") {
      Token a = tok.next();
      if (a.kind == Token::Bare && a.text == "EndTime") {
        warn_motion(loc);
        gs_.end_time_only = true;
      } else if (a.kind == Token::Bare && (a.text == "StartTime" || a.text == "All")) {
        gs_.end_time_only = false;
      } else {
        throw_at(tok.loc(a), "{} after ActiveTransform, expected StartTime, EndTime or All", Tokenizer::describe(a));
      }
    } else if (d == "TransformTimes") {
      need_options(loc, d);
      float v[2];
      numbers(tok, d, v, 2, false);
      warn_motion(loc);
    } else if (d == "MakeNamedMedium") {
      std::string name = string_arg(tok, d);
      ParamList params = parse_params(tok);
      if (named_media_.count(name)) throw_at(loc, "medium \"{}\" defined twice, expected one MakeNamedMedium per name", name);
      const Param* type = params.find("type", ParamType::String);
      if (!type)
        throw_at(loc, "MakeNamedMedium \"{}\" without \"string type\", expected \"homogeneous\", \"uniformgrid\", "
                 "\"rgbgrid\", \"cloud\" or \"nanovdb\"", name);
      scene_.media.push_back(read_medium(name, type->strings[0], params, loc, gs_.ctm, base_dir));
      named_media_[name] = int(scene_.media.size()) - 1;
    } else if (d == "MediumInterface") {
      // One name is both sides; pbrt-v4's order is inside, then outside.
      std::string inside = string_arg(tok, d), outside = inside;
      if (tok.peek().kind == Token::String) outside = string_arg(tok, d);
      gs_.medium_inside = medium_index(inside, loc);
      gs_.medium_outside = medium_index(outside, loc);
    } else if (d == "WorldEnd") {
      // pbrt-v3's terminator: accepted silently, as pbrt-v4 does when upgrading.
    } else {
      throw_at(loc, "unknown directive \"{}\", expected a pbrt-v4 directive", d);
    }
  }
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

}  // namespace

Scene load_scene(const std::string& path) {
  auto tok = Tokenizer::from_file(path, nullptr);
  return run(*tok, dir_of(path), fs::absolute(path).lexically_normal().string());
}

Scene parse_scene_string(const std::string& text, const std::string& name, const std::string& base_dir) {
  Tokenizer tok(text, name);
  return run(tok, base_dir, name);
}

}  // namespace theia
