#include "app/field_commands.h"

#include "app/field_page.h"
#include "core/image.h"
#include "core/log.h"
#include "guiding/field_file.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace theia {

namespace {

struct ColumnSummary {
  double min = 0, max = 0, mean = 0, sum = 0;
};

ColumnSummary summarise(const FieldSnapshot& s, int column) {
  ColumnSummary c;
  if (s.leaves.empty()) return c;
  c.min = c.max = s.value(0, column);
  for (size_t l = 0; l < s.leaves.size(); ++l) {
    const double v = s.value(l, column);
    c.min = std::min(c.min, v), c.max = std::max(c.max, v), c.sum += v;
  }
  c.mean = c.sum / double(s.leaves.size());
  return c;
}

nlohmann::json stats_json(const FieldFile& f, const FieldSnapshot& s) {
  nlohmann::json j = {{"iteration", s.iteration}, {"spp", s.spp}, {"leaves", s.leaves.size()},
                      {"snapshots", f.snapshots.size()}, {"wireframe_triangles", f.wireframe.p.size() / 3}};
  for (const auto& [key, value] : s.summary) j["summary"][key] = value;
  for (size_t c = 0; c < s.columns.size(); ++c) {
    const ColumnSummary cs = summarise(s, int(c));
    j["columns"][s.columns[c]] = {{"min", cs.min}, {"max", cs.max}, {"mean", cs.mean}, {"sum", cs.sum}};
  }
  auto box = [](const Bounds3& b) { return nlohmann::json{b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z}; };
  j["root_bounds"] = box(f.root_bounds);
  j["scene_bounds"] = box(f.scene_bounds);
  nlohmann::json& boxes = j["boxes"] = nlohmann::json::array();
  for (const FieldLeaf& leaf : s.leaves) boxes.push_back(box(leaf.box));
  // A mixture field's lobes, per leaf (null where a leaf has none).
  bool mixtures = false;
  for (const FieldLeaf& leaf : s.leaves) mixtures = mixtures || !leaf.lobes.empty();
  if (mixtures) {
    nlohmann::json& m = j["mixtures"] = nlohmann::json::array();
    for (const FieldLeaf& leaf : s.leaves) {
      if (leaf.lobes.empty()) {
        m.push_back(nullptr);
        continue;
      }
      nlohmann::json lobes = nlohmann::json::array();
      for (const VMMLobe& l : leaf.lobes)
        lobes.push_back({{"mu", {l.mu.x, l.mu.y, l.mu.z}},
                         {"kappa", l.kappa},
                         {"weight", l.weight},
                         {"inv_distance", l.inv_distance}});
      m.push_back({{"pivot", {leaf.pivot.x, leaf.pivot.y, leaf.pivot.z}}, {"lobes", std::move(lobes)}});
    }
  }
  nlohmann::json& rows = j["per_leaf"] = nlohmann::json::object();
  for (size_t c = 0; c < s.columns.size(); ++c) {
    nlohmann::json column = nlohmann::json::array();
    for (size_t l = 0; l < s.leaves.size(); ++l) column.push_back(s.value(l, int(c)));
    rows[s.columns[c]] = std::move(column);
  }
  return j;
}

void print_lobes(const FieldSnapshot& s, size_t leaf) {
  const FieldLeaf& l = s.leaves[leaf];
  if (l.lobes.empty()) {
    std::printf("  leaf %zu: no mixture (%s)\n", leaf,
                l.quadtree.empty() ? "it learned nothing" : "an SD-tree leaf: its quadtree guides");
    return;
  }
  std::printf("  leaf %zu: mixture seen from the pivot (%.6g, %.6g, %.6g)\n", leaf, l.pivot.x, l.pivot.y, l.pivot.z);
  std::printf("  %4s %10s %12s %30s %14s\n", "lobe", "weight", "kappa", "mean direction", "1 / distance");
  for (size_t k = 0; k < l.lobes.size(); ++k) {
    const VMMLobe& o = l.lobes[k];
    std::printf("  %4zu %10.6f %12.6g %9.5f %9.5f %9.5f %14.6g%s\n", k, o.weight, o.kappa, o.mu.x, o.mu.y, o.mu.z,
                o.inv_distance, o.weight >= kVMMActiveWeight ? "" : "  (inactive)");
  }
}

void print_stats(const std::string& path, const FieldFile& f, const FieldSnapshot& s, int leaf) {
  std::printf("%s: iteration %d (%u spp), %zu leaves, %zu snapshot(s), wireframe %zu of %llu triangles\n",
              path.c_str(), s.iteration, s.spp, s.leaves.size(), f.snapshots.size(), f.wireframe.p.size() / 3,
              (unsigned long long)f.wireframe.scene_triangles);
  for (const auto& [key, value] : s.summary) std::printf("  %-28s %.6g\n", key.c_str(), value);
  std::printf("  %-28s %12s %12s %12s %14s\n", "per leaf", "min", "mean", "max", "sum");
  for (size_t c = 0; c < s.columns.size(); ++c) {
    const ColumnSummary cs = summarise(s, int(c));
    std::printf("  %-28s %12.6g %12.6g %12.6g %14.8g\n", s.columns[c].c_str(), cs.min, cs.mean, cs.max, cs.sum);
  }
  size_t mixtures = 0;
  for (const FieldLeaf& l : s.leaves) mixtures += l.lobes.empty() ? 0 : 1;
  if (mixtures > 0)
    std::printf("  mixture field: %zu of %zu leaves fitted, %d lobes each (active: weight >= %g); --leaf N lists "
                "a leaf's lobes, --json every leaf's\n",
                mixtures, s.leaves.size(), kVMMLobes, double(kVMMActiveWeight));
  if (leaf >= 0) print_lobes(s, size_t(leaf));
}

int run_field_image(const std::string& path, int iteration, const vec3& p, int width, const std::string& out) {
  if (width < 2 || width > 8192 || width % 2 != 0)
    throw_error("--width {}: expected an even number of pixels in [2, 8192]", width);
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
    throw_error("--point {} {} {}: expected three finite coordinates", p.x, p.y, p.z);
  const FieldFile f = load_field(path);
  const FieldSnapshot& s = field_snapshot(f, iteration, path);
  const size_t leaf = s.leaf_at(p);
  if (s.leaves[leaf].quadtree.empty() && s.leaves[leaf].lobes.empty())
    log_warning("{}: leaf {} (holding {}, {}, {}) learned nothing: the image is black", path, leaf, p.x, p.y, p.z);
  const std::vector<uint8_t> rgb = field_map_rgb(s.leaves[leaf], width, p);
  // write_png_srgb encodes linear values; these are already 8-bit sRGB codes, decoded so they come back exact.
  ImageBuffer img(width, width / 2, {"R", "G", "B"});
  for (size_t i = 0; i < rgb.size(); ++i) img.data[i] = srgb8_to_linear(rgb[i]);
  write_png_srgb(out, img, 0, 1, 2);
  log_info("{}: leaf {} of iteration {}, box ({}, {}, {}) - ({}, {}, {})", out, leaf, s.iteration, s.leaves[leaf].box.min.x,
           s.leaves[leaf].box.min.y, s.leaves[leaf].box.min.z, s.leaves[leaf].box.max.x, s.leaves[leaf].box.max.y,
           s.leaves[leaf].box.max.z);
  return 0;
}

}  // namespace

FieldCommands::FieldCommands(CLI::App& app) {
  CLI::App* field = app.add_subcommand("field", "Look at a guiding field saved by render --save-field");
  field->require_subcommand(1);
  view_ = field->add_subcommand("view", "Write a static web page (open DIR/index.html) showing the field over the scene");
  view_->add_option("file", file_, "Field file")->required();
  view_->add_option("-o,--output", output_, "Output directory")->required();
  stats_ = field->add_subcommand("stats", "Print the field's statistics: field-wide, and per-leaf columns summarised");
  stats_->add_option("file", file_, "Field file")->required();
  stats_->add_flag("--json", json_, "JSON (every leaf's values too, and a mixture field's lobes), for scripts");
  stats_->add_option("--leaf", leaf_, "Also list this leaf's mixture lobes (--guiding-field vmm)");
  image_ = field->add_subcommand("image", "Write the directional distribution at a point as a cylindrical-map PNG");
  image_->add_option("file", file_, "Field file")->required();
  image_->add_option("--point", point_, "X Y Z: the point (its leaf's distribution)")->required();
  image_->add_option("-o,--output", output_, "Output PNG")->required();
  image_->add_option("--width", width_, "Image width (height: half of it)")->capture_default_str();
  for (CLI::App* c : {stats_, image_})
    c->add_option("--iteration", iteration_, "The snapshot of this iteration (default: the last)");
}

bool FieldCommands::parsed() const { return view_->parsed() || stats_->parsed() || image_->parsed(); }

int FieldCommands::run() const {
  if (image_->parsed()) return run_field_image(file_, iteration_, {point_[0], point_[1], point_[2]}, width_, output_);
  const FieldFile f = load_field(file_);
  if (view_->parsed()) {
    write_field_page(f, output_);
    log_info("{}: wrote index.html ({} snapshot(s), {} leaves in the last)", output_, f.snapshots.size(),
             f.snapshots.empty() ? 0 : f.snapshots.back().leaves.size());
    return 0;
  }
  const FieldSnapshot& s = field_snapshot(f, iteration_, file_);
  if (leaf_ >= 0 && size_t(leaf_) >= s.leaves.size())
    throw_error("--leaf {}: the snapshot has {} leaves", leaf_, s.leaves.size());
  if (json_) std::printf("%s\n", stats_json(f, s).dump(1).c_str());
  else print_stats(file_, f, s, leaf_);
  return 0;
}

}  // namespace theia
