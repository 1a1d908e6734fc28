// --save-field: the guiding field saved for `theia field view|stats|image`
// (guiding/field_file.h).  A feature of its own beside guiding: it sees the
// recorder's training samples on their way to the SD-tree and writes a
// snapshot after each guiding update.  Off (the default), it builds nothing
// and the render's samples go straight to the tree.
#pragma once

#include "app/features.h"
#include "guiding/field_file.h"
#include "scene/scene.h"

#include <memory>
#include <string>

namespace theia {

// Options of the render's own group (no prefix): --save-field, --save-field-every-iteration.
struct FieldOptions {
  std::string save_field;  // empty: not saved
  bool save_field_every_iteration = false;
};

template <class V>
void declare_options(V& v, FieldOptions& o) {
  v.output("save_field", o.save_field,
           "Save the guiding field (camera, scene wireframe, leaves, what each learned, per-leaf statistics) to this "
           "file after every iteration, for `theia field view|stats|image`; needs --guiding");
  v.output("save_field_every_iteration", o.save_field_every_iteration,
           "--save-field keeps one snapshot per iteration (the viewer's timeline), not only the last");
}
void check(const FieldOptions& o, bool guiding);

// Triangles of the scene's meshes (instances placed), decimated by vertex clustering to at most max_triangles.
FieldWireframe field_wireframe(const Scene& scene, size_t max_triangles);
FieldCamera field_camera(const Scene& scene);

class FieldFeature final : public Feature {
 public:
  FieldFeature(const FieldOptions& options, const Scene& scene, const GuidingFeature& guiding);
  ~FieldFeature() override;
  // Where the recorder hands its samples: through the field's recorder to
  // guiding's trainer when saving, else the trainer itself.
  TrainingSampleSink* sink() const;
  void add_tasks(IterationTasks& tasks) override;
  void add_participants(std::vector<CheckpointParticipant>& participants) override;
  void write_log(nlohmann::json& log) const override;

 private:
  class Sink;
  FieldOptions options_;
  const SDTree* tree_ = nullptr;
  const VMMField* vmm_ = nullptr;  // with --guiding-field vmm: what the snapshots show
  TrainingSampleSink* trainer_ = nullptr;
  std::unique_ptr<Sink> sink_;
  FieldRecorder recorder_;
  FieldFile file_;
  double seconds_ = 0.0;
  size_t bytes_ = 0;
};

}  // namespace theia
