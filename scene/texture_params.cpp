#include "scene/texture_params.h"

#include "scene/tokenizer.h"

#include <cmath>

namespace theia {

namespace {

using SpectrumUse = ParamList::SpectrumUse;

vec3 get_vector3(const ParamList& p, std::string_view name, vec3 def) {
  const Param* v = p.find(name, ParamType::Vector3);
  return v ? vec3(float(v->numbers[0]), float(v->numbers[1]), float(v->numbers[2])) : def;
}

// pbrt-v4's TextureMapping2D::Create: each mapping reads only its own
// parameters, so the others are reported unused.
void parse_mapping_2d(Texture& t, const ParamList& params, const Transform& render_from_texture,
                      const SourceLoc& loc) {
  std::string mapping = params.get_string("mapping", "uv");
  if (mapping == "uv") {
    t.mapping_kind = TextureMappingKind::UV;
    t.mapping = {params.get_float("uscale", 1), params.get_float("vscale", 1), params.get_float("udelta", 0),
                 params.get_float("vdelta", 0)};
    return;
  }
  t.texture_from_render = render_from_texture.inverse();
  if (mapping == "spherical") {
    t.mapping_kind = TextureMappingKind::Spherical;
  } else if (mapping == "cylindrical") {
    t.mapping_kind = TextureMappingKind::Cylindrical;
  } else if (mapping == "planar") {
    t.mapping_kind = TextureMappingKind::Planar;
    t.planar_s = get_vector3(params, "v1", vec3(1, 0, 0));
    t.planar_t = get_vector3(params, "v2", vec3(0, 1, 0));
    t.mapping.du = params.get_float("udelta", 0);
    t.mapping.dv = params.get_float("vdelta", 0);
  } else {
    throw_at(loc, "texture mapping \"{}\", expected \"uv\", \"spherical\", \"cylindrical\" or \"planar\"", mapping);
  }
}

// pbrt-v4's TextureMapping3D: p in the texture's object space.
void set_mapping_3d(Texture& t, const Transform& render_from_texture) {
  t.mapping_kind = TextureMappingKind::Point3D;
  t.texture_from_render = render_from_texture.inverse();
}

// "octaves" and "roughness" of fbm, wrinkled and marble.
void parse_octaves(Texture& t, const ParamList& params, const SourceLoc& loc) {
  t.octaves = params.get_int("octaves", 8);
  // pbrt-v4 takes any count; past ~30 the octaves are finer than float p
  // resolves, and a huge count would only spin (turbulence loops over all).
  if (t.octaves < 0 || t.octaves > 64) throw_at(loc, "octaves {}, expected a count from 0 to 64", t.octaves);
  t.roughness = params.get_float("roughness", 0.5f);
}

void parse_image_map(Texture& t, const std::string& name, bool is_float, const ParamList& params,
                     const SourceLoc& loc, const TextureLookups& lookups) {
  const Param* f = params.find("filename", ParamType::String);
  if (!f) throw_at(loc, "imagemap texture \"{}\" without \"string filename\", expected an image file", name);
  std::string encoding = params.get_string("encoding", "");
  if (!encoding.empty() && encoding != "sRGB" && encoding != "linear" && encoding.rfind("gamma ", 0) != 0)
    throw_at(loc, "encoding \"{}\", expected \"sRGB\", \"linear\" or \"gamma G\"", encoding);
  t.kind = TextureKind::ImageMap;
  t.image = lookups.image(f->strings[0], encoding, !is_float, f->loc);
  std::string wrap = params.get_string("wrap", "repeat");
  if (wrap == "repeat") t.wrap = WrapMode::Repeat;
  else if (wrap == "black") t.wrap = WrapMode::Black;
  else if (wrap == "clamp") t.wrap = WrapMode::Clamp;
  else if (wrap == "octahedralsphere") t.wrap = WrapMode::OctahedralSphere;
  else throw_at(loc, "wrap mode \"{}\", expected repeat, black, clamp or octahedralsphere", wrap);
  t.scale = params.get_float("scale", 1.0f);
  t.invert = params.get_bool("invert", false);
  std::string filter = params.get_string("filter", "bilinear");
  t.max_anisotropy = params.get_float("maxanisotropy", 8.0f);
  if (!(t.max_anisotropy > 0.0f)) throw_at(loc, "maxanisotropy {}, expected a positive ratio", t.max_anisotropy);
  if (filter == "point") {
    t.filter = TextureFilter::Point;
  } else if (filter == "trilinear" || filter == "ewa") {
    t.filter = filter == "ewa" ? TextureFilter::EWA : TextureFilter::Trilinear;
  } else if (filter != "bilinear") {
    throw_at(loc, "texture filter \"{}\", expected point, bilinear, trilinear or ewa", filter);
  }
}

}  // namespace

Texture parse_texture(const std::string& name, bool is_float, const std::string& cls, const ParamList& params,
                      const Transform& render_from_texture, const SourceLoc& loc, const TextureLookups& lookups) {
  Texture t;
  t.name = name;
  t.is_float = is_float;
  t.loc = loc;

  // pbrt-v4 has fbm, wrinkled and windy only as float textures and marble
  // only as a spectrum one; it stops on the others.
  bool float_only = cls == "fbm" || cls == "wrinkled" || cls == "windy";
  if (float_only && !is_float)
    throw_at(loc, "spectrum texture class \"{}\", expected \"float\" (pbrt-v4 has {} only as a float texture)", cls,
             cls);
  if (cls == "marble" && is_float)
    throw_at(loc, "float texture class \"marble\", expected \"spectrum\" (pbrt-v4 has marble only as a spectrum texture)");

  auto value_tex = [&](const char* n, float def) {
    return lookups.texture(params, n, is_float, RGB(def), SpectrumUse::Reflectance);
  };
  auto value = [&](const char* n, float def) {
    if (is_float) return RGB(params.get_float(n, def));
    return params.get_spectrum(n, SpectrumUse::Reflectance, RGB(def)).value_or(RGB(def));
  };

  if (cls == "imagemap") {
    parse_mapping_2d(t, params, render_from_texture, loc);
    parse_image_map(t, name, is_float, params, loc, lookups);
  } else if (cls == "checkerboard") {
    t.kind = TextureKind::Checkerboard;
    int dim = params.get_int("dimension", 2);
    if (dim == 2) parse_mapping_2d(t, params, render_from_texture, loc);
    else if (dim == 3) set_mapping_3d(t, render_from_texture);
    else throw_at(loc, "checkerboard dimension {}, expected 2 or 3", dim);
    t.tex1 = value_tex("tex1", 1.0f);
    t.tex2 = value_tex("tex2", 0.0f);
  } else if (cls == "scale") {
    t.kind = TextureKind::Scale;
    t.tex1 = value_tex("tex", 1.0f);
    t.tex2 = lookups.texture(params, "scale", true, RGB(1.0f), SpectrumUse::Unbounded);
  } else if (cls == "mix") {
    t.kind = TextureKind::Mix;
    t.tex1 = value_tex("tex1", 0.0f);
    t.tex2 = value_tex("tex2", 1.0f);
    t.amount = lookups.texture(params, "amount", true, RGB(0.5f), SpectrumUse::Unbounded);
  } else if (cls == "directionmix") {
    t.kind = TextureKind::DirectionMix;
    t.tex1 = value_tex("tex1", 0.0f);
    t.tex2 = value_tex("tex2", 1.0f);
    vec3 dir = render_from_texture.vector(get_vector3(params, "dir", vec3(0, 1, 0)));
    float len = glm::length(dir);
    if (!(len > 0.0f) || !std::isfinite(len))
      throw_at(loc, "directionmix \"dir\" ({}, {}, {}) in render space, expected a non-zero direction", dir.x, dir.y,
               dir.z);
    t.dir = dir / len;
  } else if (cls == "bilerp") {
    t.kind = TextureKind::Bilerp;
    parse_mapping_2d(t, params, render_from_texture, loc);
    t.corners[0] = value("v00", 0.0f);
    t.corners[1] = value("v01", 1.0f);
    t.corners[2] = value("v10", 0.0f);
    t.corners[3] = value("v11", 1.0f);
  } else if (cls == "dots") {
    t.kind = TextureKind::Dots;
    parse_mapping_2d(t, params, render_from_texture, loc);
    // pbrt-v4's DotsTexture::Create passes "inside" where the constructor
    // takes the outside texture and vice versa, so its renders show "outside"
    // (default 0) in the dots and "inside" (default 1) around them.  theia
    // renders what pbrt-v4 renders.
    t.tex1 = value_tex("outside", 0.0f);
    t.tex2 = value_tex("inside", 1.0f);
  } else if (cls == "fbm" || cls == "wrinkled") {
    t.kind = cls == "fbm" ? TextureKind::FBm : TextureKind::Wrinkled;
    set_mapping_3d(t, render_from_texture);
    parse_octaves(t, params, loc);
  } else if (cls == "windy") {
    t.kind = TextureKind::Windy;
    set_mapping_3d(t, render_from_texture);
  } else if (cls == "marble") {
    t.kind = TextureKind::Marble;
    set_mapping_3d(t, render_from_texture);
    parse_octaves(t, params, loc);
    t.marble_scale = params.get_float("scale", 1.0f);
    t.variation = params.get_float("variation", 0.2f);
  } else if (cls == "constant") {
    t.kind = TextureKind::Constant;
    t.value = value("value", 1.0f);
  } else {
    warn_at(loc, "texture class \"{}\" is not supported; substituting a constant 0.5", cls);
    params.mark_all_used();
    t.value = RGB(0.5f);
  }
  return t;
}

}  // namespace theia
