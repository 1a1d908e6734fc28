#include "scene/material_params.h"

#include "scene/conductor_spectral.h"
#include "scene/spectrum.h"
#include "scene/tokenizer.h"

#include <optional>

namespace theia {

namespace {

using SpectrumUse = ParamList::SpectrumUse;

RGB named_rgb(const char* name) { return named_spectrum_rgb(*find_named_spectrum(name), false); }

// A dielectric's index: "float eta" or "spectrum eta" (named or pairs), one
// value at 550 nm since theia renders RGB.
float parse_eta(const ParamList& p, const char* name, const SourceLoc& loc) {
  const Param* e = p.find_any(name, {ParamType::Float, ParamType::Spectrum, ParamType::Texture});
  if (!e) return 1.5f;
  float eta = 1.5f;
  if (e->type == ParamType::Float) {
    eta = float(e->numbers[0]);
  } else if (e->type == ParamType::Texture) {
    warn_at(e->loc, "textured {} is not supported; using 1.5", e->label());
  } else if (!e->strings.empty()) {
    if (const NamedSpectrum* s = find_named_spectrum(e->strings[0]); s && !s->lambda.empty())
      eta = spectrum_at(s->lambda, s->value, 550.0f);
    else
      warn_at(e->loc, "named spectrum \"{}\" is not a known index of refraction; using 1.5", e->strings[0]);
  } else {
    std::vector<float> lambda, value;
    for (size_t i = 0; i + 1 < e->numbers.size(); i += 2) {
      lambda.push_back(float(e->numbers[i]));
      value.push_back(float(e->numbers[i + 1]));
    }
    eta = spectrum_at(lambda, value, 550.0f);
  }
  if (!(eta > 0.0f) || !std::isfinite(eta)) throw_at(loc, "{} = {}, expected a positive index of refraction", e->label(), eta);
  return eta;
}

// pbrt-v4's HairMaterial: the first of sigma_a, reflectance (pbrt-v3's
// "color"), eumelanin/pheomelanin given decides the absorption, and the
// others are ignored with a warning as pbrt-v4 does; with none, eumelanin 1.3.
void parse_hair(const ParamList& params, const SourceLoc& loc, const MaterialLookups& L, Material* m) {
  auto given = [&](const char* name) -> const Param* {
    for (const Param& q : params.params)
      if (q.name == name) return &q;
    return nullptr;
  };
  const char* refl_name = given("reflectance") || !given("color") ? "reflectance" : "color";
  const char* winner = given("sigma_a") ? "sigma_a" : given(refl_name) ? refl_name : nullptr;
  for (const char* name : {"reflectance", "color", "eumelanin", "pheomelanin"}) {
    const Param* q = given(name);
    if (!q || !winner || std::string_view(name) == winner) continue;
    warn_at(q->loc, "hair: ignoring {} since \"{}\" was given", q->label(), winner);
    q->used = true;
  }
  auto ftex = [&](const char* name, float def) { return L.texture(params, name, true, RGB(def), SpectrumUse::Unbounded); };
  if (given("sigma_a")) {
    m->sigma_a = L.texture(params, "sigma_a", false, RGB(0.0f), SpectrumUse::Unbounded);
  } else if (given(refl_name)) {
    m->reflectance = L.texture(params, refl_name, false, RGB(0.5f), SpectrumUse::Reflectance);
  } else {
    bool pheo = given("pheomelanin") != nullptr;
    m->eumelanin = ftex("eumelanin", pheo ? 0.0f : 1.3f);
    m->pheomelanin = ftex("pheomelanin", 0.0f);
  }
  m->eta = params.get_float("eta", 1.55f);
  if (!(m->eta > 0.0f) || !std::isfinite(m->eta))
    throw_at(loc, "hair with eta {}, expected a positive index of refraction", m->eta);
  m->beta_m = ftex("beta_m", 0.3f);
  m->beta_n = ftex("beta_n", 0.3f);
  m->hair_alpha = ftex("alpha", 2.0f);
}

// A conductor's eta or k as the spectrum pbrt-v4 makes of it: an "rgb" by its
// unbounded upsampling, a named or tabulated spectrum as given, absent as the
// named default.  Empty for textures and for names theia does not tabulate
// (those keep the per-band value the texture lookup gives); `grey` is set
// when the spectrum is constant, where per-band Fresnel is already exact.
std::optional<SpectrumFn> conductor_spectrum(const ParamList& p, const std::string& name, const char* default_name,
                                             bool* grey) {
  const Param* e = p.find_any(name, {ParamType::RGB, ParamType::Spectrum, ParamType::Float, ParamType::Texture,
                                     ParamType::Blackbody});
  *grey = false;
  auto tabulated = [](const NamedSpectrum* s) -> std::optional<SpectrumFn> {
    if (!s || s->lambda.empty()) return std::nullopt;
    return [s](double l) { return double(spectrum_at(s->lambda, s->value, float(l))); };
  };
  if (!e) return tabulated(find_named_spectrum(default_name));
  if (e->type == ParamType::RGB && e->numbers.size() == 3) {
    RGB c(float(e->numbers[0]), float(e->numbers[1]), float(e->numbers[2]));
    *grey = c.x == c.y && c.y == c.z;
    SigmoidSpectrum s = rgb_unbounded_spectrum(glm::max(c, RGB(0.0f)));
    // A colour the sigmoid cannot reach (a zero next to a large component)
    // keeps per-band Fresnel rather than a spectrum of another colour.
    RGB back = reflectance_srgb_under_d65(s);
    if (max_component(glm::abs(back - c)) > 1e-3f * float(s.scale)) return std::nullopt;
    return [s](double l) { return s(l); };
  }
  if (e->type == ParamType::Float && !e->numbers.empty()) {
    *grey = true;
    return [v = e->numbers[0]](double) { return v; };
  }
  if (e->type != ParamType::Spectrum) return std::nullopt;
  if (!e->strings.empty()) return tabulated(find_named_spectrum(e->strings[0]));
  std::vector<float> lambda, value;
  for (size_t i = 0; i + 1 < e->numbers.size(); i += 2) {
    lambda.push_back(float(e->numbers[i]));
    value.push_back(float(e->numbers[i + 1]));
  }
  return [lambda, value](double l) { return double(spectrum_at(lambda, value, float(l))); };
}

// The conductor's spectral Fresnel table (relative to the medium of index
// `outside_eta` it sits in), or nothing where per-band eta and k are exact or
// the constants are textured.
std::vector<RGB> conductor_fresnel_table(const ParamList& p, const std::string& prefix, float outside_eta) {
  bool eta_grey = false, k_grey = false;
  std::optional<SpectrumFn> eta = conductor_spectrum(p, prefix + "eta", "metal-Cu-eta", &eta_grey);
  std::optional<SpectrumFn> k = conductor_spectrum(p, prefix + "k", "metal-Cu-k", &k_grey);
  if (!eta || !k || (eta_grey && k_grey)) return {};
  double inv = 1.0 / double(outside_eta);
  return tabulate_conductor_fresnel([&](double l) { return (*eta)(l)*inv; }, [&](double l) { return (*k)(l)*inv; });
}

}  // namespace

Material parse_material(const std::string& type, const ParamList& params, const SourceLoc& loc,
                        const MaterialLookups& L) {
  Material m;
  m.loc = loc;
  auto ftex = [&](const std::string& name, float def) {
    return L.texture(params, name, true, RGB(def), SpectrumUse::Unbounded);
  };
  auto has = [&](const std::string& name) {
    for (const Param& q : params.params)
      if (q.name == name) return true;
    return false;
  };
  // roughness, or uroughness/vroughness defaulting to it (with a prefix for coatedconductor).
  auto roughness = [&](const std::string& prefix, int* u, int* v) {
    int r = ftex(prefix + "roughness", 0.0f);
    *u = has(prefix + "uroughness") ? ftex(prefix + "uroughness", 0.0f) : r;
    *v = has(prefix + "vroughness") ? ftex(prefix + "vroughness", 0.0f) : r;
  };
  auto conductor = [&](const std::string& prefix, float outside_eta) {
    if (has("reflectance") && (has(prefix + "eta") || has(prefix + "k")))
      throw_at(loc, "{} with both \"reflectance\" and \"{}eta\"/\"{}k\", expected one of the two forms", type, prefix, prefix);
    if (has("reflectance")) {
      m.reflectance = L.texture(params, "reflectance", false, RGB(0.5f), SpectrumUse::Reflectance);
      return;
    }
    m.conductor_eta = L.texture(params, prefix + "eta", false, named_rgb("metal-Cu-eta"), SpectrumUse::Unbounded);
    m.conductor_k = L.texture(params, prefix + "k", false, named_rgb("metal-Cu-k"), SpectrumUse::Unbounded);
    m.conductor_fresnel = conductor_fresnel_table(params, prefix, outside_eta);
  };
  auto layer = [&]() {
    m.thickness = ftex("thickness", 0.01f);
    m.g = ftex("g", 0.0f);
    m.albedo = L.texture(params, "albedo", false, RGB(0.0f), SpectrumUse::Reflectance);
    m.max_depth = params.get_int("maxdepth", 10);
    m.n_samples = params.get_int("nsamples", 1);
    if (m.max_depth < 1 || m.n_samples < 1)
      throw_at(loc, "{} with maxdepth {} and nsamples {}, expected both at least 1", type, m.max_depth, m.n_samples);
  };
  m.remap_roughness = params.get_bool("remaproughness", true);

  if (type == "diffuse") {
    m.kind = MaterialKind::Diffuse;
    m.reflectance = L.texture(params, "reflectance", false, RGB(0.5f), SpectrumUse::Reflectance);
  } else if (type == "conductor") {
    m.kind = MaterialKind::Conductor;
    conductor("", 1.0f);
    roughness("", &m.uroughness, &m.vroughness);
  } else if (type == "dielectric") {
    m.kind = MaterialKind::Dielectric;
    m.eta = parse_eta(params, "eta", loc);
    roughness("", &m.uroughness, &m.vroughness);
  } else if (type == "thindielectric") {
    m.kind = MaterialKind::ThinDielectric;
    m.eta = parse_eta(params, "eta", loc);
  } else if (type == "diffusetransmission") {
    m.kind = MaterialKind::DiffuseTransmission;
    m.reflectance = L.texture(params, "reflectance", false, RGB(0.25f), SpectrumUse::Reflectance);
    m.transmittance = L.texture(params, "transmittance", false, RGB(0.25f), SpectrumUse::Reflectance);
    m.scale = params.get_float("scale", 1.0f);
  } else if (type == "coateddiffuse") {
    m.kind = MaterialKind::CoatedDiffuse;
    m.reflectance = L.texture(params, "reflectance", false, RGB(0.5f), SpectrumUse::Reflectance);
    roughness("", &m.uroughness, &m.vroughness);
    m.eta = parse_eta(params, "eta", loc);
    layer();
  } else if (type == "coatedconductor") {
    m.kind = MaterialKind::CoatedConductor;
    roughness("interface.", &m.uroughness, &m.vroughness);
    m.eta = parse_eta(params, "interface.eta", loc);
    conductor("conductor.", m.eta);
    roughness("conductor.", &m.conductor_uroughness, &m.conductor_vroughness);
    layer();
  } else if (type == "hair") {
    m.kind = MaterialKind::Hair;
    parse_hair(params, loc, L, &m);
  } else if (type == "mix") {
    m.kind = MaterialKind::Mix;
    const Param* names = params.find("materials", ParamType::String);
    if (!names || names->strings.size() != 2)
      throw_at(loc, "mix material needs \"string materials\" with two names, expected [ \"a\" \"b\" ]");
    for (int i = 0; i < 2; ++i) m.mix[i] = L.named_material(names->strings[size_t(i)], names->loc);
    m.amount = ftex("amount", 0.5f);
  } else if (type == "interface" || type == "none" || type.empty()) {
    m.kind = MaterialKind::Interface;
  } else {
    warn_at(loc, "material \"{}\" is not supported yet; substituting diffuse 0.5", type);
    params.mark_all_used();
    m.kind = MaterialKind::Diffuse;
    m.reflectance = L.texture(ParamList{}, "reflectance", false, RGB(0.5f), SpectrumUse::Reflectance);
    return m;
  }
  if (has("displacement")) m.displacement = ftex("displacement", 0.0f);
  std::string normal_map = params.get_string("normalmap", "");
  if (!normal_map.empty()) m.normal_map = L.image(normal_map, "linear", loc);
  return m;
}

}  // namespace theia
