#include "app/field_feature.h"

#include "core/atomic_file.h"
#include "core/bytes.h"
#include "core/hash.h"
#include "core/log.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <unordered_set>
#include <cmath>

namespace theia {

void check(const FieldOptions& o, bool guiding) {
  if (o.save_field_every_iteration && o.save_field.empty())
    throw_error("--save-field-every-iteration needs --save-field FILE");
  if (!o.save_field.empty() && !guiding)
    throw_error("--save-field {}: there is no field to save without --guiding (or --guiding-auto)", o.save_field);
}

namespace {

struct PlacedMesh {
  const TriangleMesh* mesh;
  Transform to_render;
};

std::vector<PlacedMesh> placed_meshes(const Scene& scene) {
  std::vector<PlacedMesh> placed;
  auto add = [&](int shape, const Transform& t) {
    const Shape& s = scene.shapes[size_t(shape)];
    if (s.kind == ShapeKind::TriangleMesh && s.mesh >= 0) placed.push_back({&scene.meshes[size_t(s.mesh)], t});
  };
  for (int shape : scene.top_level_shapes) add(shape, Transform());
  for (const Instance& inst : scene.instances)
    for (int shape : scene.prototypes[size_t(inst.prototype)].shapes) add(shape, inst.render_from_instance);
  return placed;
}

// Vertex clustering: vertices snap to the centres of a res^3 grid over the
// scene, triangles that collapse or repeat go.  Small features vanish, large
// shapes keep their outline (a random subset of triangles would leave holes).
std::vector<vec3> clustered_triangles(const std::vector<PlacedMesh>& placed, const Bounds3& b, uint32_t res) {
  const vec3 cell = glm::max(b.diagonal() / float(res), vec3(1e-20f));
  auto cell_of = [&](const vec3& p) {
    const glm::uvec3 c = glm::min(glm::uvec3(glm::max((p - b.min) / cell, vec3(0.0f))), glm::uvec3(res - 1));
    return uint64_t(c.x) | uint64_t(c.y) << 21 | uint64_t(c.z) << 42;
  };
  auto centre = [&](uint64_t c) {
    return b.min + (vec3(float(c & 0x1fffff), float(c >> 21 & 0x1fffff), float(c >> 42)) + 0.5f) * cell;
  };
  std::vector<vec3> out;
  std::unordered_set<uint64_t> seen;
  for (const PlacedMesh& m : placed)
    for (size_t t = 0; t < m.mesh->triangle_count(); ++t) {
      std::array<uint64_t, 3> c;
      for (size_t k = 0; k < 3; ++k) c[k] = cell_of(m.to_render.point(m.mesh->p[m.mesh->indices[3 * t + k]]));
      if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
      std::array<uint64_t, 3> sorted = c;
      std::sort(sorted.begin(), sorted.end());
      if (!seen.insert(hash(sorted[0], sorted[1], sorted[2])).second) continue;
      for (uint64_t k : c) out.push_back(centre(k));
    }
  return out;
}

}  // namespace

FieldWireframe field_wireframe(const Scene& scene, size_t max_triangles) {
  FieldWireframe w;
  const std::vector<PlacedMesh> placed = placed_meshes(scene);
  Bounds3 bounds;
  for (const PlacedMesh& m : placed) {
    w.scene_triangles += m.mesh->triangle_count();
    for (uint32_t i : m.mesh->indices) {
      const vec3 p = m.to_render.point(m.mesh->p[i]);
      bounds.min = glm::min(bounds.min, p), bounds.max = glm::max(bounds.max, p);
    }
  }
  if (w.scene_triangles <= max_triangles) {
    for (const PlacedMesh& m : placed)
      for (uint32_t i : m.mesh->indices) w.p.push_back(m.to_render.point(m.mesh->p[i]));
    return w;
  }
  for (uint32_t res = 1024;; res /= 2) {
    w.p = clustered_triangles(placed, bounds, res);
    if (w.p.size() / 3 <= max_triangles || res <= 16) return w;
  }
}

FieldCamera field_camera(const Scene& scene) {
  const Transform& t = scene.camera.render_from_camera;
  FieldCamera c;
  c.eye = t.point(vec3(0.0f));
  c.forward = glm::normalize(t.vector(vec3(0, 0, 1)));
  c.up = glm::normalize(t.vector(vec3(0, 1, 0)));
  c.right = glm::normalize(t.vector(vec3(1, 0, 0)));
  c.width = scene.film.width;
  c.height = scene.film.height;
  c.mirrored = glm::dot(c.right, glm::cross(c.forward, c.up)) < 0.0f ? 1 : 0;
  if (scene.camera.kind != CameraKind::Perspective) {
    c.fov_y_degrees = 0.0f;
  } else if (c.width >= c.height) {
    c.fov_y_degrees = scene.camera.fov;  // pbrt-v4's fov spans the shorter image axis
  } else {
    const float half = std::tan(0.5f * radians(scene.camera.fov)) * float(c.height) / float(c.width);
    c.fov_y_degrees = 2.0f * std::atan(half) * 180.0f / kPi;
  }
  return c;
}

// Trains, then records the iteration's samples (in the order the recorder sorted them) if the tree took them.
class FieldFeature::Sink final : public TrainingSampleSink {
 public:
  Sink(FieldFeature& f) : f_(f) {}
  bool wants_nee_samples() const override { return f_.trainer_->wants_nee_samples(); }
  void consume(std::span<const TrainingSample> samples) override {
    const SDTreeStats before = f_.tree_->stats();
    f_.trainer_->consume(samples);
    const SDTreeStats after = f_.tree_->stats();
    // What the tree did not take (a field no longer training) is not the field's data.
    if (after.pending_recorded + after.pending_dropped == before.pending_recorded + before.pending_dropped) return;
    std::vector<SDTreeSample> converted(samples.size());
    for (size_t i = 0; i < samples.size(); ++i) converted[i] = sd_tree_sample(samples[i]);
    f_.recorder_.add(*f_.tree_, converted);
  }

 private:
  FieldFeature& f_;
};

// Scenes beyond this many triangles are decimated (field_wireframe): enough to see the shapes, light for a browser.
constexpr size_t kWireframeTriangles = 60000;

FieldFeature::FieldFeature(const FieldOptions& options, const Scene& scene, const GuidingFeature& guiding)
    : options_(options), tree_(guiding.tree()), vmm_(guiding.vmm()), trainer_(guiding.trainer()) {
  if (options_.save_field.empty()) return;
  if (!tree_) {
    log_warning("--save-field {}: guiding is off in this render, so there is no field to save", options_.save_field);
    return;
  }
  sink_ = std::make_unique<Sink>(*this);
  file_.camera = field_camera(scene);
  file_.scene_bounds = Bounds3();
  file_.root_bounds = tree_->root_bounds();
  file_.wireframe = field_wireframe(scene, kWireframeTriangles);
  for (const vec3& p : file_.wireframe.p) file_.scene_bounds.min = glm::min(file_.scene_bounds.min, p),
                                          file_.scene_bounds.max = glm::max(file_.scene_bounds.max, p);
  if (file_.scene_bounds.empty()) file_.scene_bounds = file_.root_bounds;
}

FieldFeature::~FieldFeature() = default;

TrainingSampleSink* FieldFeature::sink() const { return sink_ ? sink_.get() : trainer_; }

// After guiding's update (tasks of a slot run in the order added; guiding adds its update first).
void FieldFeature::add_tasks(IterationTasks& tasks) {
  if (!sink_) return;
  tasks.add(BetweenIterationSlot::GuidingUpdate, [this](const IterationInfo& it) {
    const auto start = std::chrono::steady_clock::now();
    FieldSnapshot snap = recorder_.snapshot(*tree_, it.index, it.spp_end, vmm_);
    if (!options_.save_field_every_iteration) file_.snapshots.clear();
    file_.snapshots.push_back(std::move(snap));
    const std::vector<uint8_t> bytes = serialize_field(file_);
    write_text_atomically(options_.save_field, std::string(bytes.begin(), bytes.end()));
    bytes_ = bytes.size();
    seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  });
}

// The snapshots so far and what the recorder has seen: without them a
// resumed render's file would start over at the resume.
void FieldFeature::add_participants(std::vector<CheckpointParticipant>& participants) {
  if (!sink_) return;
  participants.push_back({"field", 1,
                          [this] {
                            ByteWriter w;
                            w.put_vector(serialize_field(file_));
                            w.put_vector(recorder_.serialize());
                            return w.bytes;
                          },
                          [this](const CheckpointSection& section) {
                            const std::string what = "checkpoint section 'field'";
                            if (section.version != 1) throw_error("{} has version {}, this build reads 1", what, section.version);
                            ByteReader r(section.bytes, what);
                            file_ = deserialize_field(r.get_vector<uint8_t>(), what);
                            recorder_.restore(r.get_vector<uint8_t>(), what);
                            if (r.pos != r.size) throw_error("{}: {} bytes left over", what, r.size - r.pos);
                          }});
}

void FieldFeature::write_log(nlohmann::json& log) const {
  if (!sink_) return;
  log["guiding"]["field_file"] = {{"path", options_.save_field},
                                  {"snapshots", file_.snapshots.size()},
                                  {"bytes", bytes_},
                                  {"wireframe_triangles", file_.wireframe.p.size() / 3},
                                  {"scene_triangles", file_.wireframe.scene_triangles},
                                  {"seconds", seconds_}};
}

}  // namespace theia
