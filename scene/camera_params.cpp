#include "scene/camera_params.h"

#include <algorithm>

namespace theia {

void read_camera(const std::string& type, const ParamList& params, const SourceLoc& loc, CameraParams& c) {
  // A later Camera replaces an earlier one entirely, as in pbrt-v4.
  Transform render_from_camera = c.render_from_camera;
  c = CameraParams{};
  c.render_from_camera = render_from_camera;
  if (type == "perspective" || type == "realistic") {
    c.kind = CameraKind::Perspective;
  } else if (type == "orthographic") {
    c.kind = CameraKind::Orthographic;
  } else if (type == "spherical") {
    c.kind = CameraKind::Spherical;
  } else {
    c.kind = CameraKind::Perspective;
  }
  if (type != "perspective" && c.kind == CameraKind::Perspective) {
    // A lens system (or an unknown camera) has no perspective equivalent of its parameters.
    warn_at(loc, "camera \"{}\" is not supported; substituting perspective", type);
    params.mark_all_used();
    return;
  }
  // pbrt-v4 reads the lens and the screen window for every camera; the
  // spherical camera then ignores them.
  if (c.kind == CameraKind::Perspective) c.fov = params.get_float("fov", c.fov);
  c.lens_radius = params.get_float("lensradius", c.lens_radius);
  c.focal_distance = params.get_float("focaldistance", c.focal_distance);
  if (const Param* f = params.find("frameaspectratio", ParamType::Float)) {
    float a = float(f->numbers[0]);
    float w[4] = {-a, a, -1.0f, 1.0f};
    if (a <= 1.0f) w[0] = -1.0f, w[1] = 1.0f, w[2] = -1.0f / a, w[3] = 1.0f / a;
    std::copy(w, w + 4, c.screen_window);
    c.has_screen_window = true;
  }
  if (const Param* s = params.find("screenwindow", ParamType::Float)) {
    if (s->numbers.size() != 4) throw_at(s->loc, "{} has {} values, expected 4", s->label(), s->numbers.size());
    for (int i = 0; i < 4; ++i) c.screen_window[i] = float(s->numbers[size_t(i)]);
    c.has_screen_window = true;
  }
  if (c.kind == CameraKind::Spherical) {
    const Param* m = params.find("mapping", ParamType::String);
    std::string mapping = m ? m->strings[0] : "equalarea";
    if (mapping == "equalarea") {
      c.mapping = SphericalMapping::EqualArea;
    } else if (mapping == "equirectangular") {
      c.mapping = SphericalMapping::Equirectangular;
    } else {
      throw_at(m->loc, "spherical camera mapping \"{}\", expected \"equalarea\" or \"equirectangular\"", mapping);
    }
  }
}

void read_film(const std::string& type, const ParamList& params, const SourceLoc& loc, FilmParams& film) {
  if (type != "rgb") warn_at(loc, "film \"{}\" is not supported; treated as \"rgb\"", type);
  film.width = params.get_int("xresolution", film.width);
  film.height = params.get_int("yresolution", film.height);
  film.filename = params.get_string("filename", film.filename);
  if (film.width <= 0 || film.height <= 0)
    throw_at(loc, "film resolution {}x{}, expected positive sizes", film.width, film.height);
  // Pixels are addressed with 32 bits (the film, sample indices, checkpoints).
  if (uint64_t(film.width) * uint64_t(film.height) >= (uint64_t(1) << 32))
    throw_at(loc, "film resolution {}x{}, expected fewer than 2^32 pixels", film.width, film.height);
}

void read_pixel_filter(const std::string& type, const ParamList& params, const SourceLoc& loc, FilterParams& f) {
  // pbrt-v4's default radii per filter; "lanczos" is accepted for pbrt-v4's "sinc".
  f = FilterParams{};
  float r = 1.5f;
  if (type == "box") f.kind = FilterKind::Box, r = 0.5f;
  else if (type == "triangle") f.kind = FilterKind::Triangle, r = 2.0f;
  else if (type == "gaussian") f.kind = FilterKind::Gaussian;
  else if (type == "mitchell") f.kind = FilterKind::Mitchell, r = 2.0f;
  else if (type == "sinc" || type == "lanczos") f.kind = FilterKind::Lanczos, r = 4.0f;
  else {
    warn_at(loc, "pixel filter \"{}\" is not supported; substituting gaussian", type);
    f.kind = FilterKind::Gaussian;
    params.mark_all_used();  // one warning for the filter, not one per parameter
  }
  f.radius = vec2(params.get_float("xradius", r), params.get_float("yradius", r));
  if (f.kind == FilterKind::Gaussian) f.sigma = params.get_float("sigma", 0.5f);
  if (f.kind == FilterKind::Mitchell) {
    f.b = params.get_float("B", 1.0f / 3.0f);
    f.c = params.get_float("C", 1.0f / 3.0f);
  }
  if (f.kind == FilterKind::Lanczos) f.tau = params.get_float("tau", 3.0f);
}

}  // namespace theia
