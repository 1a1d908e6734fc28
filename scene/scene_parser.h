// The pbrt-v4 parser's state, shared by the two files that make it (internal
// to scene/): directives.cpp reads each directive and its arguments,
// parser.cpp turns them into the scene's cameras, materials, lights and shapes.
#pragma once

#include "core/math.h"
#include "scene/light_params.h"
#include "scene/params.h"
#include "scene/scene.h"
#include "scene/tokenizer.h"

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <vector>

namespace theia::parse_detail {

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

const char* pushed_name(char kind);
// A path named in a file, relative to that file's folder.
std::string resolve(const std::string& base_dir, const std::string& name);
std::string dir_of(const std::string& path);
std::string canonical_path(const std::string& path);
bool is_usable(const Transform& t);

class SceneParser {
 public:
  explicit SceneParser(Scene& scene) : scene_(scene) {
    named_coords_["world"] = Transform();
    if (!scene.path.empty()) includes_.push_back(canonical_path(scene.path));
  }

  void parse(Tokenizer& tok, const std::string& base_dir);
  void finish(const SourceLoc& end);

 private:
  // ---- directives: each has a handler, found by its name
  struct Directive {
    Tokenizer& tok;
    std::string_view name;
    SourceLoc loc;
    const std::string& base_dir;  // where the files it names are
  };
  using Handler = void (SceneParser::*)(Directive&);
  static Handler handler_of(std::string_view name);
  ParamList typed_params(Directive& d, std::string& type, const ParamList* defaults);
  // the options block
  // Camera, Film and PixelFilter: a type and parameters for `build`, before WorldBegin.
  template <void (SceneParser::*build)(const std::string&, ParamList&, const SourceLoc&)>
  void on_options_block(Directive& d);
  void on_settings(Directive& d);  // Sampler, Integrator, Accelerator
  void on_color_space(Directive& d);
  void on_option(Directive& d);
  void on_transform_times(Directive& d);
  void on_world_begin(Directive& d);
  void on_world_end(Directive& d);
  // transforms
  void on_matrix(Directive& d);  // Transform, ConcatTransform
  void on_translate(Directive& d);
  void on_scale(Directive& d);
  void on_rotate(Directive& d);
  void on_look_at(Directive& d);
  void on_identity(Directive& d);
  void on_coordinate_system(Directive& d);
  void on_coord_sys_transform(Directive& d);
  void on_active_transform(Directive& d);
  // nesting
  void on_push(Directive& d);  // AttributeBegin, TransformBegin
  void on_pop(Directive& d);   // AttributeEnd, TransformEnd
  void on_object_begin(Directive& d);
  void on_object_end(Directive& d);
  void on_object_instance(Directive& d);
  void on_include(Directive& d);  // Include, Import
  // the world
  void on_shape(Directive& d);
  void on_material(Directive& d);
  void on_named_material(Directive& d);
  void on_make_named_material(Directive& d);
  void on_texture(Directive& d);
  void on_light_source(Directive& d);
  void on_area_light_source(Directive& d);
  void on_reverse_orientation(Directive& d);
  void on_attribute(Directive& d);
  void on_make_named_medium(Directive& d);
  void on_medium_interface(Directive& d);

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

}  // namespace theia::parse_detail
