#include "scene/params.h"

#include "core/color.h"
#include "core/log.h"
#include "scene/spectrum.h"

#include <cmath>
#include <limits>

namespace theia {

namespace {

bool lookup_type(std::string_view s, ParamType* t) {
  static const std::pair<std::string_view, ParamType> kTypes[] = {
      {"integer", ParamType::Integer}, {"float", ParamType::Float},         {"point2", ParamType::Point2},
      {"vector2", ParamType::Vector2}, {"point3", ParamType::Point3},       {"vector3", ParamType::Vector3},
      {"point", ParamType::Point3},    {"vector", ParamType::Vector3},      {"normal3", ParamType::Normal3},
      {"normal", ParamType::Normal3},  {"rgb", ParamType::RGB},             {"spectrum", ParamType::Spectrum},
      {"blackbody", ParamType::Blackbody}, {"bool", ParamType::Bool},       {"string", ParamType::String},
      {"texture", ParamType::Texture},
  };
  for (auto& [name, type] : kTypes)
    if (name == s) {
      *t = type;
      return true;
    }
  return false;
}

int tuple_size(ParamType t) {
  switch (t) {
    case ParamType::Point2:
    case ParamType::Vector2: return 2;
    case ParamType::Point3:
    case ParamType::Vector3:
    case ParamType::Normal3:
    case ParamType::RGB: return 3;
    default: return 1;
  }
}

// Splits "type name" on whitespace.
bool split_decl(std::string_view s, std::string_view* type, std::string_view* name) {
  auto ws = [](char c) { return c == ' ' || c == '\t'; };
  size_t b = 0;
  while (b < s.size() && ws(s[b])) ++b;
  size_t e = b;
  while (e < s.size() && !ws(s[e])) ++e;
  size_t nb = e;
  while (nb < s.size() && ws(s[nb])) ++nb;
  size_t ne = nb;
  while (ne < s.size() && !ws(s[ne])) ++ne;
  size_t rest = ne;
  while (rest < s.size() && ws(s[rest])) ++rest;
  *type = s.substr(b, e - b);
  *name = s.substr(nb, ne - nb);
  return !type->empty() && !name->empty() && rest == s.size();
}

void add_value(Tokenizer& tok, Param& p, const Token& t) {
  // The location (a string copy) is built only on error: this runs once per number.
  if (p.type == ParamType::Bool) {
    if ((t.kind == Token::Bare || t.kind == Token::String) && (t.text == "true" || t.text == "false")) {
      p.bools.push_back(t.text == "true");
      return;
    }
    throw_at(tok.loc(t), "value {} for {}, expected true or false", Tokenizer::describe(t), p.label());
  }
  if (p.type == ParamType::String || p.type == ParamType::Texture) {
    if (t.kind != Token::String) throw_at(tok.loc(t), "value {} for {}, expected a quoted string", Tokenizer::describe(t), p.label());
    p.strings.push_back(tok.string_value(t));
    return;
  }
  if (p.type == ParamType::Spectrum && t.kind == Token::String) {
    if (!p.numbers.empty())
      throw_at(tok.loc(t), "value {} for {}, expected a number", Tokenizer::describe(t), p.label());
    p.strings.push_back(tok.string_value(t));
    return;
  }
  if (t.kind != Token::Bare || !p.strings.empty())
    throw_at(tok.loc(t), "value {} for {}, expected a number", Tokenizer::describe(t), p.label());
  double v;
  if (!parse_number(t.text, &v)) throw_at(tok.loc(t), "bad number \"{}\" for {}, expected a number", t.text, p.label());
  // from_chars accepts "nan" and "inf", and a double may overflow the float it
  // becomes: either would reach the render as NaN/Inf, so neither gets in.
  if (!std::isfinite(v) || std::abs(v) > double(std::numeric_limits<float>::max()))
    throw_at(tok.loc(t), "value {} for {}, expected a finite number (within float range)", t.text, p.label());
  if (p.type == ParamType::Integer && (v != std::floor(v) || std::abs(v) > 2147483647.0))
    throw_at(tok.loc(t), "value {} for {}, expected an integer", t.text, p.label());
  p.numbers.push_back(v);
}

void check_count(const Param& p) {
  size_t n = p.type == ParamType::Bool ? p.bools.size() : p.numbers.size() + p.strings.size();
  int k = tuple_size(p.type);
  if (n == 0) throw_at(p.loc, "{} has no values, expected at least one", p.label());
  if (k > 1 && n % size_t(k) != 0) throw_at(p.loc, "{} has {} values, expected a multiple of {}", p.label(), n, k);
  if (p.type == ParamType::Blackbody && n != 1)
    throw_at(p.loc, "{} has {} values, expected one temperature in Kelvin", p.label(), n);
  if (p.type == ParamType::Spectrum) {
    if (!p.strings.empty() && n != 1) throw_at(p.loc, "{} has {} names, expected one", p.label(), n);
    if (p.strings.empty() && n % 2 != 0)
      throw_at(p.loc, "{} has {} values, expected (wavelength, value) pairs", p.label(), n);
  }
  if (p.type == ParamType::Texture && n != 1) throw_at(p.loc, "{} has {} values, expected one texture name", p.label(), n);
}

}  // namespace

ParamList parse_params(Tokenizer& tok) {
  ParamList list;
  while (tok.peek().kind == Token::String) {
    Token decl = tok.next();
    Param p;
    p.loc = tok.loc(decl);
    std::string decl_text = tok.string_value(decl);
    std::string_view type, name;
    if (!split_decl(decl_text, &type, &name))
      throw_at(p.loc, "parameter declaration \"{}\", expected \"type name\"", decl_text);
    p.type_name = std::string(type);
    p.name = std::string(name);
    if (!lookup_type(type, &p.type))
      throw_at(p.loc, "unknown parameter type \"{}\" in \"{}\", expected one of integer, float, point2, vector2, "
               "point3, vector3, normal3, rgb, spectrum, blackbody, bool, string, texture", type, decl_text);

    Token v = tok.next();
    if (v.kind == Token::LBracket) {
      while (true) {
        Token t = tok.next();
        if (t.kind == Token::RBracket) break;
        if (t.kind == Token::End)
          throw_at(tok.loc(t), "unexpected end of file inside the value list of {} opened at line {}, expected ']'",
                   p.label(), v.line);
        if (t.kind == Token::LBracket) throw_at(tok.loc(t), "'[' inside the value list of {}, expected a value or ']'", p.label());
        add_value(tok, p, t);
      }
    } else if (v.kind == Token::End) {
      throw_at(tok.loc(v), "unexpected end of file after {}, expected its value", p.label());
    } else if (v.kind == Token::RBracket) {
      throw_at(tok.loc(v), "']' after {}, expected its value", p.label());
    } else {
      add_value(tok, p, v);
    }
    check_count(p);
    list.params.push_back(std::move(p));
  }
  return list;
}

const Param* ParamList::find(std::string_view name, ParamType type) const {
  for (const Param& p : params)
    if (p.type == type && p.name == name) {
      p.used = true;
      return &p;
    }
  return nullptr;
}

const Param* ParamList::find_any(std::string_view name, std::initializer_list<ParamType> types) const {
  for (const Param& p : params)
    if (p.name == name)
      for (ParamType t : types)
        if (p.type == t) {
          p.used = true;
          return &p;
        }
  return nullptr;
}

// A parameter read as one value (or one point) must have exactly that many,
// as pbrt-v4 insists: extra values are a mistake, not something to ignore.
static const Param* with_count(const Param* p, size_t have, size_t expected) {
  if (p && have != expected) throw_at(p->loc, "{} has {} values, expected {}", p->label(), have, expected);
  return p;
}

float ParamList::get_float(std::string_view name, float def) const {
  const Param* p = find(name, ParamType::Float);
  return with_count(p, p ? p->numbers.size() : 0, 1) ? float(p->numbers[0]) : def;
}
int ParamList::get_int(std::string_view name, int def) const {
  const Param* p = find(name, ParamType::Integer);
  return with_count(p, p ? p->numbers.size() : 0, 1) ? int(p->numbers[0]) : def;
}
bool ParamList::get_bool(std::string_view name, bool def) const {
  const Param* p = find(name, ParamType::Bool);
  return with_count(p, p ? p->bools.size() : 0, 1) ? p->bools[0] != 0 : def;
}
std::string ParamList::get_string(std::string_view name, const std::string& def) const {
  const Param* p = find(name, ParamType::String);
  return with_count(p, p ? p->strings.size() : 0, 1) ? p->strings[0] : def;
}
vec3 ParamList::get_point3(std::string_view name, vec3 def) const {
  const Param* p = find(name, ParamType::Point3);
  return with_count(p, p ? p->numbers.size() : 0, 3) ? vec3(float(p->numbers[0]), float(p->numbers[1]), float(p->numbers[2]))
                                                      : def;
}
std::span<const double> ParamList::get_floats(std::string_view name) const {
  const Param* p = find(name, ParamType::Float);
  return p ? std::span<const double>(p->numbers) : std::span<const double>();
}

std::optional<RGB> ParamList::get_spectrum(std::string_view name, SpectrumUse use, RGB fallback) const {
  std::optional<RGB> c = get_spectrum_srgb(name, use, fallback);
  // Unbounded spectra (a conductor's eta and k) are per-band constants, not
  // colours: they stay in the sRGB bands (see conductor_fresnel).
  if (c && use != SpectrumUse::Unbounded) return srgb_to_working(*c);
  return c;
}

std::optional<RGB> ParamList::get_spectrum_srgb(std::string_view name, SpectrumUse use, RGB fallback) const {
  const Param* p = find_any(name, {ParamType::RGB, ParamType::Spectrum, ParamType::Blackbody});
  if (!p) return std::nullopt;
  bool illuminant = use == SpectrumUse::Illuminant;
  if (p->type == ParamType::RGB) {
    if (p->numbers.size() != 3) throw_at(p->loc, "{} has {} values, expected 3", p->label(), p->numbers.size());
    for (double v : p->numbers)
      if (v < 0.0) throw_at(p->loc, "{} has the negative value {}, expected values >= 0", p->label(), v);
    return RGB(float(p->numbers[0]), float(p->numbers[1]), float(p->numbers[2]));
  }
  if (p->type == ParamType::Blackbody) return blackbody_rgb(float(p->numbers[0]));
  if (!p->strings.empty()) {
    if (const NamedSpectrum* s = find_named_spectrum(p->strings[0])) return named_spectrum_rgb(*s, illuminant);
    warn_at(p->loc, "named spectrum \"{}\" is not supported yet; substituting ({}, {}, {})", p->strings[0], fallback.x,
            fallback.y, fallback.z);
    return fallback;
  }
  std::vector<float> lambda, value;
  for (size_t i = 0; i + 1 < p->numbers.size(); i += 2) {
    if (!lambda.empty() && float(p->numbers[i]) <= lambda.back())
      throw_at(p->loc, "{} has wavelength {} after {}, expected ascending wavelengths", p->label(), p->numbers[i], lambda.back());
    if (p->numbers[i + 1] < 0.0)
      throw_at(p->loc, "{} has the negative value {} at {} nm, expected values >= 0", p->label(), p->numbers[i + 1],
               p->numbers[i]);
    lambda.push_back(float(p->numbers[i]));
    value.push_back(float(p->numbers[i + 1]));
  }
  return illuminant ? spectrum_to_rgb_illuminant(lambda, value) : spectrum_to_rgb_reflectance(lambda, value);
}

static std::vector<vec3> to_vec3(const Param* p) {
  std::vector<vec3> v;
  if (!p) return v;
  v.resize(p->numbers.size() / 3);
  for (size_t i = 0; i < v.size(); ++i)
    v[i] = vec3(float(p->numbers[3 * i]), float(p->numbers[3 * i + 1]), float(p->numbers[3 * i + 2]));
  return v;
}

static std::vector<vec2> to_vec2(const Param* p) {
  std::vector<vec2> v;
  if (!p) return v;
  v.resize(p->numbers.size() / 2);
  for (size_t i = 0; i < v.size(); ++i) v[i] = vec2(float(p->numbers[2 * i]), float(p->numbers[2 * i + 1]));
  return v;
}

bool mesh_from_params(const ParamList& params, const SourceLoc& loc, const char* shape, size_t per_prim,
                      TriangleMesh* m) {
  const Param* P = params.find("P", ParamType::Point3);
  if (!P) throw_at(loc, "{} without \"point3 P\", expected vertex positions", shape);
  m->p = to_vec3(P);
  if (const Param* ind = params.find("indices", ParamType::Integer)) {
    if (ind->numbers.size() % per_prim != 0)
      throw_at(ind->loc, "{} has {} values, expected a multiple of {}", ind->label(), ind->numbers.size(), per_prim);
    m->indices.resize(ind->numbers.size());
    for (size_t i = 0; i < m->indices.size(); ++i) {
      double v = ind->numbers[i];
      if (v < 0 || v >= double(m->p.size()))
        throw_at(ind->loc, "index {} in {}, expected an index below the {} vertices", v, ind->label(), m->p.size());
      m->indices[i] = uint32_t(v);
    }
  } else if (m->p.size() == per_prim) {
    for (uint32_t i = 0; i < per_prim; ++i) m->indices.push_back(i);
  } else {
    throw_at(loc, "{} without \"integer indices\", expected indices unless there are exactly {} vertices", shape, per_prim);
  }
  const Param* N = params.find("N", ParamType::Normal3);
  m->n = to_vec3(N);
  if (N && m->n.size() != m->p.size()) {
    warn_at(N->loc, "{} has {} normals for {} vertices; ignored", N->label(), m->n.size(), m->p.size());
    m->n.clear();
  }
  const Param* uv = params.find("uv", ParamType::Point2);
  m->uv = to_vec2(uv);
  if (uv && m->uv.size() != m->p.size()) {
    warn_at(uv->loc, "{} has {} uvs for {} vertices; ignored", uv->label(), m->uv.size(), m->p.size());
    m->uv.clear();
  }
  if (const Param* s = params.find("S", ParamType::Vector3)) warn_at(s->loc, "per-vertex tangents {} are not supported; ignored", s->label());
  params.find("faceIndices", ParamType::Integer);
  return !m->indices.empty();
}

void ParamList::mark_all_used() const {
  for (const Param& p : params) p.used = true;
}

void ParamList::add_defaults(const ParamList& defaults) {
  for (const Param& d : defaults.params) {
    bool given = false;
    for (const Param& p : params) given |= p.name == d.name;
    if (given) continue;
    params.push_back(d);
    params.back().may_be_unused = true;
  }
}

void ParamList::report_unused() const {
  for (const Param& p : params)
    if (!p.used && !p.may_be_unused) warn_at(p.loc, "unused parameter {}", p.label());
}

}  // namespace theia
