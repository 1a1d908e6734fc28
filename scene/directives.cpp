// The pbrt-v4 directives, each read by a handler of its own and found by
// its name; what they build is made in parser.cpp.
#include "core/log.h"
#include "scene/medium_params.h"
#include "scene/scene_parser.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>

namespace theia::parse_detail {

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
    Directive d{tok, t.text, loc, base_dir};
    Handler handler = handler_of(d.name);
    if (!handler) throw_at(loc, "unknown directive \"{}\", expected a pbrt-v4 directive", d.name);
    (this->*handler)(d);
  }
}

SceneParser::Handler SceneParser::handler_of(std::string_view name) {
  using P = SceneParser;
  static const std::unordered_map<std::string_view, Handler> kHandlers = {
      // the options block
      {"Camera", &P::on_options_block<&P::camera>}, {"Film", &P::on_options_block<&P::film>},
      {"PixelFilter", &P::on_options_block<&P::pixel_filter>},
      {"Sampler", &P::on_settings}, {"Integrator", &P::on_settings}, {"Accelerator", &P::on_settings},
      {"ColorSpace", &P::on_color_space}, {"Option", &P::on_option}, {"TransformTimes", &P::on_transform_times},
      {"WorldBegin", &P::on_world_begin}, {"WorldEnd", &P::on_world_end},
      // transforms
      {"Transform", &P::on_matrix}, {"ConcatTransform", &P::on_matrix}, {"Translate", &P::on_translate},
      {"Scale", &P::on_scale}, {"Rotate", &P::on_rotate}, {"LookAt", &P::on_look_at}, {"Identity", &P::on_identity},
      {"CoordinateSystem", &P::on_coordinate_system}, {"CoordSysTransform", &P::on_coord_sys_transform},
      {"ActiveTransform", &P::on_active_transform},
      // nesting: attributes, objects, files
      {"AttributeBegin", &P::on_push}, {"TransformBegin", &P::on_push}, {"AttributeEnd", &P::on_pop},
      {"TransformEnd", &P::on_pop}, {"ObjectBegin", &P::on_object_begin}, {"ObjectEnd", &P::on_object_end},
      {"ObjectInstance", &P::on_object_instance}, {"Include", &P::on_include}, {"Import", &P::on_include},
      // the world
      {"Shape", &P::on_shape}, {"Material", &P::on_material}, {"NamedMaterial", &P::on_named_material},
      {"MakeNamedMaterial", &P::on_make_named_material}, {"Texture", &P::on_texture},
      {"LightSource", &P::on_light_source}, {"AreaLightSource", &P::on_area_light_source},
      {"ReverseOrientation", &P::on_reverse_orientation}, {"Attribute", &P::on_attribute},
      {"MakeNamedMedium", &P::on_make_named_medium}, {"MediumInterface", &P::on_medium_interface},
  };
  auto it = kHandlers.find(name);
  return it == kHandlers.end() ? nullptr : it->second;
}

// The common shape of a directive: `Name "type" params...`, the graphics
// state's attributes (Attribute "shape" ...) as the parameters' defaults.
ParamList SceneParser::typed_params(Directive& d, std::string& type, const ParamList* defaults) {
  type = string_arg(d.tok, d.name);
  ParamList params = parse_params(d.tok);
  if (defaults) params.add_defaults(*defaults);
  return params;
}

// ---- the options block

template <void (SceneParser::*build)(const std::string&, ParamList&, const SourceLoc&)>
void SceneParser::on_options_block(Directive& d) {
  need_options(d.loc, d.name);
  std::string type;
  ParamList params = typed_params(d, type, nullptr);
  (this->*build)(type, params, d.loc);
  params.report_unused();
}

// Sampler, Integrator and Accelerator: theia has its own; what it takes of them.
void SceneParser::on_settings(Directive& d) {
  need_options(d.loc, d.name);
  std::string type;
  ParamList params = typed_params(d, type, nullptr);
  if (d.name == "Sampler") {
    scene_.settings.spp = params.get_int("pixelsamples", scene_.settings.spp);
    if (scene_.settings.spp <= 0)
      throw_at(params.find("pixelsamples", ParamType::Integer)->loc, "\"integer pixelsamples\" is {}, expected a "
               "positive count", scene_.settings.spp);
    log_info("{}: note: theia uses its own sampler; of Sampler \"{}\" only pixelsamples is used", format_loc(d.loc), type);
  } else if (d.name == "Integrator") {
    scene_.settings.max_depth = params.get_int("maxdepth", scene_.settings.max_depth);
    if (scene_.settings.max_depth < 0)
      throw_at(params.find("maxdepth", ParamType::Integer)->loc, "\"integer maxdepth\" is {}, expected zero or more",
               scene_.settings.max_depth);
    log_info("{}: note: theia has its own integrator; of Integrator \"{}\" only maxdepth is used", format_loc(d.loc), type);
  } else {
    log_info("{}: note: Accelerator \"{}\" ignored; theia uses Embree", format_loc(d.loc), type);
    params.mark_all_used();
  }
  params.report_unused();
}

void SceneParser::on_color_space(Directive& d) {
  std::string name = string_arg(d.tok, d.name);
  if (name != "srgb") warn_at(d.loc, "color space \"{}\" is not supported; theia renders in linear sRGB", name);
}

void SceneParser::on_option(Directive& d) {
  ParamList params = parse_params(d.tok);
  if (params.params.size() != 1) throw_at(d.loc, "Option with {} parameters, expected one", params.params.size());
  warn_at(d.loc, "Option {} is ignored by theia", params.params[0].label());
}

void SceneParser::on_transform_times(Directive& d) {
  need_options(d.loc, d.name);
  float v[2];
  numbers(d.tok, d.name, v, 2, false);
  warn_motion(d.loc);
}

void SceneParser::on_world_begin(Directive& d) {
  need_options(d.loc, d.name);
  in_world_ = true;
  gs_.ctm = Transform();
  gs_.end_time_only = false;
  named_coords_["world"] = gs_.ctm;
}

// pbrt-v3's terminator: accepted silently, as pbrt-v4 does when upgrading.
void SceneParser::on_world_end(Directive&) {}

// ---- transforms

void SceneParser::on_matrix(Directive& d) {
  float m[16];
  numbers(d.tok, d.name, m, 16, true);
  // The 16 values are pbrt's transposed (column-major) matrix, which is GLM's layout.
  Transform tr(glm::make_mat4(m));
  if (d.name == "Transform") set_ctm(tr);
  else apply(tr);
}

void SceneParser::on_translate(Directive& d) {
  float v[3];
  numbers(d.tok, d.name, v, 3, false);
  apply(Transform(glm::translate(mat4(1.0f), vec3(v[0], v[1], v[2])), glm::translate(mat4(1.0f), -vec3(v[0], v[1], v[2]))));
}

void SceneParser::on_scale(Directive& d) {
  float v[3];
  numbers(d.tok, d.name, v, 3, false);
  apply(Transform(glm::scale(mat4(1.0f), vec3(v[0], v[1], v[2]))));
}

void SceneParser::on_rotate(Directive& d) {
  float v[4];
  numbers(d.tok, d.name, v, 4, false);
  vec3 axis(v[1], v[2], v[3]);
  if (glm::length(axis) == 0.0f) throw_at(d.loc, "Rotate about a zero axis, expected a non-zero axis");
  mat4 r = glm::rotate(mat4(1.0f), radians(v[0]), glm::normalize(axis));
  apply(Transform(r, glm::transpose(r)));
}

void SceneParser::on_look_at(Directive& d) {
  float v[9];
  numbers(d.tok, d.name, v, 9, false);
  vec3 eye(v[0], v[1], v[2]), look(v[3], v[4], v[5]), up(v[6], v[7], v[8]);
  vec3 dir = look - eye;
  if (glm::length(dir) == 0.0f) throw_at(d.loc, "LookAt with the eye at the look-at point, expected distinct points");
  if (!(glm::length(up) > 0.0f)) throw_at(d.loc, "LookAt with a zero up vector, expected a non-zero up vector");
  dir = glm::normalize(dir);
  vec3 right = glm::cross(glm::normalize(up), dir);
  if (!(glm::length(right) > 0.0f)) throw_at(d.loc, "LookAt with the up vector along the view direction, expected them not parallel");
  right = glm::normalize(right);
  vec3 new_up = glm::cross(dir, right);
  // pbrt-v4's left-handed camera frame: x right, y up, z forward.
  mat4 world_from_camera(vec4(right, 0), vec4(new_up, 0), vec4(dir, 0), vec4(eye, 1));
  apply(Transform(world_from_camera).inverse());
}

void SceneParser::on_identity(Directive&) { set_ctm(Transform()); }

void SceneParser::on_coordinate_system(Directive& d) { named_coords_[string_arg(d.tok, d.name)] = gs_.ctm; }

void SceneParser::on_coord_sys_transform(Directive& d) {
  std::string name = string_arg(d.tok, d.name);
  auto it = named_coords_.find(name);
  if (it == named_coords_.end()) warn_at(d.loc, "unknown coordinate system \"{}\"; CoordSysTransform ignored", name);
  else set_ctm(it->second);
}

void SceneParser::on_active_transform(Directive& d) {
  Token a = d.tok.next();
  if (a.kind == Token::Bare && a.text == "EndTime") {
    warn_motion(d.loc);
    gs_.end_time_only = true;
  } else if (a.kind == Token::Bare && (a.text == "StartTime" || a.text == "All")) {
    gs_.end_time_only = false;
  } else {
    throw_at(d.tok.loc(a), "{} after ActiveTransform, expected StartTime, EndTime or All", Tokenizer::describe(a));
  }
}

// ---- nesting: attributes, objects, files

void SceneParser::on_push(Directive& d) {
  if (d.name == "AttributeBegin") need_world(d.loc, d.name);
  else if (!warned_transform_begin_) {
    warned_transform_begin_ = true;
    warn_at(d.loc, "TransformBegin/TransformEnd are deprecated; use AttributeBegin/AttributeEnd");
  }
  stack_.push_back({d.name == "AttributeBegin" ? 'a' : 't', gs_, d.loc});
}

void SceneParser::on_pop(Directive& d) {
  if (d.name == "AttributeEnd") need_world(d.loc, d.name);
  char kind = d.name == "AttributeEnd" ? 'a' : 't';
  if (stack_.empty()) throw_at(d.loc, "{} without {}", d.name, pushed_name(kind));
  if (stack_.back().kind != kind)
    throw_at(d.loc, "{} while {} at {} is open, expected its end first", d.name, pushed_name(stack_.back().kind),
             format_loc(stack_.back().loc));
  if (kind == 'a') {
    gs_ = std::move(stack_.back().state);
  } else {
    gs_.ctm = stack_.back().state.ctm;
  }
  stack_.pop_back();
}

void SceneParser::on_object_begin(Directive& d) {
  need_world(d.loc, d.name);
  std::string name = string_arg(d.tok, d.name);
  if (object_ >= 0)
    throw_at(d.loc, "ObjectBegin \"{}\" inside the definition of \"{}\", expected ObjectEnd first", name,
             scene_.prototypes[size_t(object_)].name);
  if (objects_.count(name)) throw_at(d.loc, "object \"{}\" redefined, expected a new name", name);
  stack_.push_back({'o', gs_, d.loc});
  object_ = int(scene_.prototypes.size());
  objects_[name] = object_;
  scene_.prototypes.push_back({name, {}});
}

void SceneParser::on_object_end(Directive& d) {
  need_world(d.loc, d.name);
  if (object_ < 0) throw_at(d.loc, "ObjectEnd without ObjectBegin");
  if (stack_.back().kind != 'o')
    throw_at(d.loc, "ObjectEnd while {} at {} is open, expected its end first", pushed_name(stack_.back().kind),
             format_loc(stack_.back().loc));
  gs_ = std::move(stack_.back().state);
  stack_.pop_back();
  object_ = -1;
}

void SceneParser::on_object_instance(Directive& d) {
  need_world(d.loc, d.name);
  std::string name = string_arg(d.tok, d.name);
  if (object_ >= 0) throw_at(d.loc, "ObjectInstance inside an object definition, expected ObjectEnd first");
  auto it = objects_.find(name);
  if (it == objects_.end()) throw_at(d.loc, "unknown object \"{}\", expected a name defined by ObjectBegin", name);
  if (!is_usable(gs_.ctm)) warn_at(d.loc, "ObjectInstance \"{}\" under a transform that is not invertible or not finite; instance ignored", name);
  else scene_.instances.push_back({it->second, gs_.ctm});
}

void SceneParser::on_include(Directive& d) {
  if (d.name == "Import") need_world(d.loc, d.name);
  std::string path = resolve(d.base_dir, string_arg(d.tok, d.name));
  IncludeGuard guard(includes_, path, d.loc, d.name);
  auto sub = Tokenizer::from_file(path, &d.loc);
  std::string dir = dir_of(path);
  if (d.name == "Include") {
    parse(*sub, dir);
    return;
  }
  // Import may not change the importer's graphics state (pbrt-v4 parses it on its own copy).
  GraphicsState saved = gs_;
  size_t depth = stack_.size();
  parse(*sub, dir);
  if (stack_.size() != depth)
    throw_at(stack_.back().loc, "{} without its end in the imported file, expected it closed there",
             pushed_name(stack_.back().kind));
  gs_ = std::move(saved);
}

// ---- the world

void SceneParser::on_shape(Directive& d) {
  need_world(d.loc, d.name);
  std::string type;
  ParamList params = typed_params(d, type, &gs_.shape_attrs);
  shape(type, params, d.loc, d.base_dir);
  params.report_unused();
}

void SceneParser::on_material(Directive& d) {
  need_world(d.loc, d.name);
  std::string type;
  ParamList params = typed_params(d, type, &gs_.material_attrs);
  gs_.material = make_material(type, "", params, d.loc, d.base_dir);
  params.report_unused();
}

void SceneParser::on_named_material(Directive& d) {
  need_world(d.loc, d.name);
  std::string name = string_arg(d.tok, d.name);
  auto it = named_materials_.find(name);
  if (it == named_materials_.end())
    throw_at(d.loc, "unknown named material \"{}\", expected a name defined by MakeNamedMaterial", name);
  gs_.material = it->second;
}

void SceneParser::on_make_named_material(Directive& d) {
  need_world(d.loc, d.name);
  std::string name;
  ParamList params = typed_params(d, name, &gs_.material_attrs);
  if (named_materials_.count(name)) throw_at(d.loc, "named material \"{}\" redefined, expected a new name", name);
  const Param* type = params.find("type", ParamType::String);
  if (!type) throw_at(d.loc, "MakeNamedMaterial \"{}\" without \"string type\", expected the material type", name);
  named_materials_[name] = make_material(type->strings[0], name, params, d.loc, d.base_dir);
  params.report_unused();
}

void SceneParser::on_texture(Directive& d) {
  need_world(d.loc, d.name);
  std::string name = string_arg(d.tok, d.name);
  std::string type = string_arg(d.tok, d.name);
  std::string cls;
  ParamList params = typed_params(d, cls, &gs_.texture_attrs);
  texture(name, type, cls, params, d.loc, d.base_dir);
  params.report_unused();
}

void SceneParser::on_light_source(Directive& d) {
  need_world(d.loc, d.name);
  std::string type;
  ParamList params = typed_params(d, type, &gs_.light_attrs);
  light_source(type, params, d.loc, d.base_dir);
  params.report_unused();
}

void SceneParser::on_area_light_source(Directive& d) {
  need_world(d.loc, d.name);
  std::string type;
  ParamList params = typed_params(d, type, &gs_.light_attrs);
  area_light_source(type, params, d.loc, d.base_dir);
  params.report_unused();
}

void SceneParser::on_reverse_orientation(Directive& d) {
  need_world(d.loc, d.name);
  gs_.reverse_orientation = !gs_.reverse_orientation;
}

void SceneParser::on_attribute(Directive& d) {
  std::string target = string_arg(d.tok, d.name);
  ParamList params = parse_params(d.tok);
  ParamList* attrs = target == "shape"      ? &gs_.shape_attrs
                     : target == "light"    ? &gs_.light_attrs
                     : target == "material" ? &gs_.material_attrs
                     : target == "texture"  ? &gs_.texture_attrs
                                            : nullptr;
  if (target == "medium") {
    warn_at(d.loc, "participating media are not supported yet; Attribute \"medium\" ignored");
  } else if (!attrs) {
    throw_at(d.loc, "unknown attribute target \"{}\", expected \"shape\", \"light\", \"material\", \"medium\" or \"texture\"", target);
  } else {
    for (Param& p : params.params) {
      std::erase_if(attrs->params, [&](const Param& q) { return q.name == p.name; });
      attrs->params.push_back(std::move(p));
    }
  }
}

void SceneParser::on_make_named_medium(Directive& d) {
  std::string name = string_arg(d.tok, d.name);
  ParamList params = parse_params(d.tok);
  if (named_media_.count(name)) throw_at(d.loc, "medium \"{}\" defined twice, expected one MakeNamedMedium per name", name);
  const Param* type = params.find("type", ParamType::String);
  if (!type)
    throw_at(d.loc, "MakeNamedMedium \"{}\" without \"string type\", expected \"homogeneous\", \"uniformgrid\", "
             "\"rgbgrid\", \"cloud\" or \"nanovdb\"", name);
  scene_.media.push_back(read_medium(name, type->strings[0], params, d.loc, gs_.ctm, d.base_dir));
  named_media_[name] = int(scene_.media.size()) - 1;
}

void SceneParser::on_medium_interface(Directive& d) {
  // One name is both sides; pbrt-v4's order is inside, then outside.
  std::string inside = string_arg(d.tok, d.name), outside = inside;
  if (d.tok.peek().kind == Token::String) outside = string_arg(d.tok, d.name);
  gs_.medium_inside = medium_index(inside, d.loc);
  gs_.medium_outside = medium_index(outside, d.loc);
}

}  // namespace theia::parse_detail
