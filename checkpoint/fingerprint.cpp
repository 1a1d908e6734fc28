#include "checkpoint/fingerprint.h"

#include "core/hash.h"

#include <fstream>
#include <iterator>

namespace theia {

namespace {

struct Hasher {
  uint64_t h = 0;
  void bytes(const void* p, size_t n) { h = hash_bytes(p, n, h); }
  template <typename T>
  void pod(const T& v) {
    bytes(&v, sizeof(T));
  }
  template <typename T>
  void vec(const std::vector<T>& v) {
    pod(v.size());
    bytes(v.data(), v.size() * sizeof(T));
  }
  void str(const std::string& s) { bytes(s.data(), s.size()); }
};

}  // namespace

uint64_t scene_fingerprint(const Scene& s) {
  Hasher h;
  if (std::ifstream f{s.path, std::ios::binary}) {
    std::string text((std::istreambuf_iterator<char>(f)), {});
    h.str(text);
  }
  for (const TriangleMesh& m : s.meshes) {
    h.vec(m.p);
    h.vec(m.n);
    h.vec(m.uv);
    h.vec(m.indices);
  }
  for (const CurveSet& c : s.curves) {
    h.pod(c.type);
    h.vec(c.cp);
    h.vec(c.n);
  }
  for (const Shape& sh : s.shapes) {
    h.pod(sh.kind);
    h.pod(sh.mesh);
    h.pod(sh.curves);
    h.pod(sh.sphere);
    h.pod(sh.disk);
    h.pod(sh.cylinder);
    h.pod(sh.render_from_object);
    h.pod(sh.reverse_orientation);
    h.pod(sh.transform_swaps_handedness);
    h.pod(sh.material);
    h.pod(sh.area_light);
    h.pod(sh.alpha);
    h.pod(sh.holdout);
  }
  // Every field that changes the image (names and source locations do not).
  for (const Material& m : s.materials) {
    for (int v : {int(m.kind), m.reflectance, m.transmittance, m.uroughness, m.vroughness, int(m.remap_roughness),
                  m.conductor_eta, m.conductor_k, m.conductor_uroughness, m.conductor_vroughness, m.thickness, m.g,
                  m.albedo, m.max_depth, m.n_samples, m.mix[0], m.mix[1], m.amount, m.displacement, m.normal_map, m.sigma_a, m.eumelanin, m.pheomelanin, m.beta_m,
                  m.beta_n, m.hair_alpha})
      h.pod(v);
    h.pod(m.scale);
    h.pod(m.eta);
  }
  for (const Texture& t : s.textures) {
    h.pod(t.kind);
    h.pod(t.value);
    h.pod(t.mapping);
    h.pod(t.image);
    h.pod(t.scale);
    h.pod(t.is_float);
    h.pod(t.wrap);
    h.pod(t.invert);
    h.pod(t.filter);
    h.pod(t.max_anisotropy);
    h.pod(t.tex1);
    h.pod(t.tex2);
    h.pod(t.amount);
    h.pod(t.mapping_kind);
    h.pod(t.planar_s);
    h.pod(t.planar_t);
    h.pod(t.texture_from_render);
    h.pod(t.corners);
    h.pod(t.octaves);
    h.pod(t.roughness);
    h.pod(t.marble_scale);
    h.pod(t.variation);
    h.pod(t.dir);
  }
  for (const Image& img : s.images) h.vec(img.pixels);
  for (const Light& l : s.lights) {
    h.pod(l.kind);
    h.pod(l.L);
    h.pod(l.two_sided);
    h.pod(l.is_virtual);
    h.pod(l.shape);
    h.pod(l.position);
    h.pod(l.direction);
    h.pod(l.cos_falloff_start);
    h.pod(l.cos_falloff_end);
    h.pod(l.image);
    h.pod(l.illuminance);
    h.pod(l.fov);
    h.vec(l.triangle_scale);
    h.pod(l.power);
    h.pod(l.render_from_light);
  }
  for (const Instance& i : s.instances) {
    h.pod(i.prototype);
    h.pod(i.render_from_instance);
  }
  // Media only where the scene has them, so other scenes keep their fingerprints.
  if (s.has_media()) {
    for (const Shape& sh : s.shapes) {
      h.pod(sh.medium_inside);
      h.pod(sh.medium_outside);
    }
    for (const Medium& m : s.media) {
      h.pod(m.kind);
      h.pod(m.sigma_a);
      h.pod(m.sigma_s);
      h.pod(m.Le);
      h.pod(m.g);
      h.pod(m.nx);
      h.pod(m.ny);
      h.pod(m.nz);
      h.vec(m.density);
      h.pod(m.p0);
      h.pod(m.p1);
      h.vec(m.sigma_a_grid);
      h.vec(m.sigma_s_grid);
      h.vec(m.Le_grid);
      h.pod(m.Le_scale);
      h.vec(m.Le_scale_grid);
      h.vec(m.temperature);
      h.pod(m.temperature_offset);
      h.pod(m.temperature_scale);
      h.pod(m.cloud_density);
      h.pod(m.wispiness);
      h.pod(m.frequency);
      h.pod(m.render_from_medium);
    }
    h.pod(s.camera_medium);
  }
  h.pod(s.camera.kind);
  h.pod(s.camera.mapping);
  h.pod(s.camera.render_from_camera);
  h.pod(s.camera.fov);
  h.pod(s.camera.lens_radius);
  h.pod(s.camera.focal_distance);
  h.pod(s.camera.screen_window);
  h.pod(s.film.width);
  h.pod(s.film.height);
  h.pod(s.filter.kind);
  h.pod(s.filter.radius);
  h.pod(s.filter.sigma);
  h.pod(s.filter.b);
  h.pod(s.filter.c);
  h.pod(s.filter.tau);
  return h.h;
}

}  // namespace theia
