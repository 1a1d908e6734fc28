// A directive's parameter list ("type name" value...), checked for shape at
// parse time and looked up by (name, type) like pbrt-v4's ParameterDictionary.
// Every lookup marks the parameter used; what is left unused is reported.
#pragma once

#include "scene/tokenizer.h"

#include <optional>
#include <span>
#include <string>
#include <vector>

namespace theia {

enum class ParamType {
  Integer, Float, Point2, Vector2, Point3, Vector3, Normal3, RGB, Spectrum, Blackbody, Bool, String, Texture
};

struct Param {
  ParamType type = ParamType::Float;
  std::string type_name;          // as written ("point", "normal3", ...)
  std::string name;
  std::vector<double> numbers;    // numeric types, and "spectrum" given as (lambda, value) pairs
  std::vector<std::string> strings;  // string, texture, and "spectrum" given by name
  std::vector<uint8_t> bools;
  SourceLoc loc;
  mutable bool used = false;
  bool may_be_unused = false;     // from Attribute: a default, not a request
  std::string label() const { return "\"" + type_name + " " + name + "\""; }
};

class ParamList {
 public:
  std::vector<Param> params;

  // The parameter with this name and type, marked used; nullptr if absent.
  const Param* find(std::string_view name, ParamType type) const;
  // The parameter with this name of any of the types, marked used.
  const Param* find_any(std::string_view name, std::initializer_list<ParamType> types) const;

  float get_float(std::string_view name, float def) const;
  int get_int(std::string_view name, int def) const;
  bool get_bool(std::string_view name, bool def) const;
  std::string get_string(std::string_view name, const std::string& def) const;
  vec3 get_point3(std::string_view name, vec3 def) const;
  std::span<const double> get_floats(std::string_view name) const;  // empty if absent

  // A colour given as "rgb", "spectrum" (pairs or a name) or "blackbody",
  // reduced to RGB for its use (see scene/spectrum.h); nullopt if absent.
  // Named spectra not in the table warn and give `fallback`.
  enum class SpectrumUse { Reflectance, Unbounded, Illuminant };
  // A colour parameter (rgb, blackbody, spectrum or named spectrum) in the
  // renderer's working colour space (core/color.h); Unbounded ones (eta, k)
  // are optical constants per band and stay in the sRGB bands.
  std::optional<RGB> get_spectrum(std::string_view name, SpectrumUse use, RGB fallback) const;
  // The same in linear sRGB, as the scene states it.
  std::optional<RGB> get_spectrum_srgb(std::string_view name, SpectrumUse use, RGB fallback) const;

  // Marks everything used (for a type theia substitutes wholesale).
  void mark_all_used() const;
  // Adds `defaults` (from Attribute) for names not given here.
  void add_defaults(const ParamList& defaults);
  // One warning per parameter nobody looked up, as pbrt-v4 reports them.
  void report_unused() const;
};

// A mesh shape's "P", "indices" (per_prim per primitive; implied when there
// are exactly per_prim vertices), "N" and "uv", in object space; N or uv of the
// wrong length are dropped with a warning.  False if there are no primitives.
bool mesh_from_params(const ParamList& params, const SourceLoc& loc, const char* shape, size_t per_prim,
                      TriangleMesh* m);

// Parses `"type name" value | [ values ]` pairs until the next token is not a string.
ParamList parse_params(Tokenizer& tok);

}  // namespace theia
