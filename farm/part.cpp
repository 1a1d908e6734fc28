#include "farm/part.h"

#include "core/atomic_file.h"
#include "core/log.h"
#include "core/stats.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <numeric>

namespace theia {

namespace fs = std::filesystem;

namespace {

constexpr const char* kSumPrefix = "sum.";

uint32_t parse_count(std::string_view s, const std::string& text) {
  uint32_t v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size())
    throw_error("--sample-range {}: expected BEGIN:END with whole numbers 0 <= BEGIN < END", text);
  return v;
}

std::string hex(uint64_t v) { return fmt::format("{:016x}", v); }

uint64_t from_hex(const nlohmann::json& j, const std::string& what) {
  const std::string s = j.get<std::string>();
  uint64_t v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v, 16);
  if (ec != std::errc() || end != s.data() + s.size()) throw_error("{}: bad fingerprint '{}'", what, s);
  return v;
}

std::string range_text(const SampleRange& r) { return fmt::format("[{}, {})", r.begin, r.end); }

// The image options whose values differ between two parts, by name.
std::string differing_options(const nlohmann::json& a, const nlohmann::json& b) {
  std::vector<std::string> names;
  for (auto it = a.begin(); it != a.end(); ++it)
    if (!b.contains(it.key()) || b[it.key()] != it.value())
      names.push_back(fmt::format("{} ({} vs {})", it.key(), it.value().dump(),
                                  b.contains(it.key()) ? b[it.key()].dump() : "absent"));
  for (auto it = b.begin(); it != b.end(); ++it)
    if (!a.contains(it.key())) names.push_back(fmt::format("{} (absent vs {})", it.key(), it.value().dump()));
  return names.empty() ? "none by name (a different build?)" : fmt::format("{}", fmt::join(names, ", "));
}

std::string learned(const PartInfo& p) {
  return p.learns.empty() ? "nothing" : fmt::format("{}", fmt::join(p.learns, " and "));
}

std::string scene_of(const Part& p) { return p.log.is_object() ? p.log.value("scene", "?") : "?"; }

void check_same_frame(const Part& a, const Part& b) {
  if (a.image.width != b.image.width || a.image.height != b.image.height)
    throw_error("{} is {}x{} but {} is {}x{}: not parts of one frame", b.path, b.image.width, b.image.height, a.path,
                a.image.width, a.image.height);
  if (a.info.scene_fingerprint != b.info.scene_fingerprint)
    throw_error("{} and {} were rendered from different scenes ({} vs {}: the scene file or something it loads "
                "differs)",
                a.path, b.path, scene_of(a), scene_of(b));
  if (a.info.seed != b.info.seed)
    throw_error("{} and {} were rendered with different seeds ({} vs {})", a.path, b.path, a.info.seed, b.info.seed);
  if (a.info.learns != b.info.learns)
    throw_error("{} learned {} on its own but {} learned {}: parts of one frame learn the same way (image options "
                "that differ: {})",
                a.path, learned(a.info), b.path, learned(b.info),
                differing_options(a.info.image_options, b.info.image_options));
  if (a.info.options_fingerprint != b.info.options_fingerprint)
    throw_error("{} and {} were rendered with different image options: {}", a.path, b.path,
                differing_options(a.info.image_options, b.info.image_options));
  if (a.info.spp != b.info.spp)
    throw_error("{} and {} split frames of different spp ({} vs {})", a.path, b.path, a.info.spp, b.info.spp);
}

}  // namespace

SampleRange parse_sample_range(const std::string& text) {
  const size_t colon = text.find(':');
  if (colon == std::string::npos)
    throw_error("--sample-range {}: expected BEGIN:END with whole numbers 0 <= BEGIN < END", text);
  SampleRange r{parse_count(std::string_view(text).substr(0, colon), text),
                parse_count(std::string_view(text).substr(colon + 1), text)};
  if (r.begin >= r.end) throw_error("--sample-range {}: BEGIN must be below END", text);
  return r;
}

nlohmann::json part_json(const PartInfo& p) {
  return {{"sample_range", {p.range.begin, p.range.end}},
          {"spp", p.spp},
          {"scene_fingerprint", hex(p.scene_fingerprint)},
          {"options_fingerprint", hex(p.options_fingerprint)},
          {"seed", p.seed},
          {"image_options", p.image_options},
          {"learns", p.learns}};
}

PartInfo part_from_json(const nlohmann::json& j, const std::string& what) {
  if (!j.is_object() || !j.contains("part"))
    throw_error("{}: not a part of a split frame (no \"part\" in its log; render it with --sample-range)", what);
  try {
    const nlohmann::json& p = j.at("part");
    PartInfo info;
    info.range = {p.at("sample_range").at(0).get<uint32_t>(), p.at("sample_range").at(1).get<uint32_t>()};
    info.spp = p.at("spp").get<int>();
    info.scene_fingerprint = from_hex(p.at("scene_fingerprint"), what);
    info.options_fingerprint = from_hex(p.at("options_fingerprint"), what);
    info.seed = p.at("seed").get<uint32_t>();
    info.image_options = p.at("image_options");
    info.learns = p.value("learns", std::vector<std::string>{});
    if (info.range.begin >= info.range.end || info.range.end > uint32_t(std::max(info.spp, 0)))
      throw_error("{}: sample range {} is not within its {} spp", what, range_text(info.range), info.spp);
    return info;
  } catch (const nlohmann::json::exception& e) {
    throw_error("{}: malformed part log: {}", what, e.what());
  }
}

ImageBuffer part_image(const ImageBuffer& resolved, const ImageBuffer& sums) {
  ImageBuffer out(resolved.width, resolved.height, resolved.channels);
  for (const std::string& c : sums.channels) out.channels.push_back(c);
  const size_t a = resolved.channels.size(), b = sums.channels.size(), n = out.channels.size();
  out.data.resize(out.pixel_count() * n);
  for (size_t i = 0; i < out.pixel_count(); ++i) {
    std::copy_n(resolved.data.begin() + std::ptrdiff_t(i * a), a, out.data.begin() + std::ptrdiff_t(i * n));
    std::copy_n(sums.data.begin() + std::ptrdiff_t(i * b), b, out.data.begin() + std::ptrdiff_t(i * n + a));
  }
  return out;
}

Part read_part(const std::string& exr_path) {
  Part part;
  part.path = exr_path;
  const std::string log_path = fs::path(exr_path).replace_extension(".json").string();
  std::ifstream f(log_path);
  if (!f) throw_error("{}: cannot read the part's log {} (a part is PART.exr with PART.json beside it)", exr_path,
                      log_path);
  try {
    part.log = nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception& e) {
    throw_error("{}: not valid JSON: {}", log_path, e.what());
  }
  part.info = part_from_json(part.log, log_path);
  const auto& spp = part.log.at("scheduler").at("spp_per_pixel");
  const uint32_t want = part.info.range.end - part.info.range.begin;
  if (spp.at("min").get<uint32_t>() != want || spp.at("max").get<uint32_t>() != want)
    throw_error("{}: the part is incomplete ({}-{} of its {} samples per pixel)", log_path,
                spp.at("min").get<uint32_t>(), spp.at("max").get<uint32_t>(), want);
  part.image = read_image_file(exr_path);
  return part;
}

std::vector<size_t> check_parts(const std::vector<Part>& parts) {
  if (parts.empty()) throw_error("merge: no parts given");
  for (size_t i = 1; i < parts.size(); ++i) check_same_frame(parts[0], parts[i]);
  std::vector<size_t> order(parts.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return parts[a].info.range.begin < parts[b].info.range.begin; });
  uint32_t at = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    const Part& p = parts[order[k]];
    if (p.info.range.begin < at)
      throw_error("{} {} and {} {} overlap", parts[order[k - 1]].path, range_text(parts[order[k - 1]].info.range),
                  p.path, range_text(p.info.range));
    if (p.info.range.begin > at)
      throw_error("samples [{}, {}) of the frame's {} are in no part (missing before {})", at, p.info.range.begin,
                  p.info.spp, p.path);
    at = p.info.range.end;
  }
  if (at != uint32_t(parts[0].info.spp))
    throw_error("samples [{}, {}) of the frame's {} are in no part (missing after {})", at, parts[0].info.spp,
                parts[0].info.spp, parts[order.back()].path);
  return order;
}

void merge_parts(const std::vector<Part>& parts, const std::vector<size_t>& order, Film& film) {
  film.clear();
  uint64_t dropped = 0;
  for (size_t k : order) {
    add_film_sums(film, parts[k].image, kSumPrefix, parts[k].path);
    dropped += parts[k].log.value("dropped_samples", uint64_t(0));
  }
  film.dropped = dropped;
}

int run_merge(const std::vector<std::string>& paths, const std::string& output, std::string log_path) {
  const auto t0 = std::chrono::steady_clock::now();
  if (fs::path(output).extension() != ".exr") throw_error("-o {}: the output must be an .exr file", output);
  if (log_path.empty()) log_path = fs::path(output).replace_extension(".json").string();
  std::vector<Part> parts;
  for (const std::string& p : paths) parts.push_back(read_part(p));
  const std::vector<size_t> order = check_parts(parts);
  Film film(parts[0].image.width, parts[0].image.height, sums_have_aov_events(parts[0].image, kSumPrefix));
  merge_parts(parts, order, film);
  const ImageBuffer image = resolve_film(film);
  const std::string png = fs::path(output).replace_extension(".png").string();
  write_exr(output, image);
  write_png_srgb(png, image, 0, 1, 2);

  nlohmann::json log;
  log["merged_from"] = nlohmann::json::array();
  for (size_t k : order)
    log["merged_from"].push_back({{"part", parts[k].path},
                                  {"sample_range", {parts[k].info.range.begin, parts[k].info.range.end}},
                                  {"render_seconds", parts[k].log.at("time").value("render", 0.0)}});
  const PartInfo& first = parts[0].info;
  log["scene"] = parts[0].log.value("scene", "");
  log["resolution"] = {image.width, image.height};
  log["options"] = parts[0].log.value("options", nlohmann::json::object());
  log["options"].erase("checkpoint_dir");
  log["scheduler"]["spp_per_pixel"] = {{"min", first.spp}, {"max", first.spp}};
  log["fingerprints"] = {{"scene", hex(first.scene_fingerprint)}, {"options", hex(first.options_fingerprint)}};
  log["dropped_samples"] = film.dropped.load();
  if (film.aov_events()) log["aov_event_layers"] = event_layer_names();
  log["learned_per_part"] = first.learns;
  log["equals_single_process_render"] = first.learns.empty();
  log["time"] = {{"merge", seconds_since(t0)}};
  log["outputs"] = {output, png};
  write_text_atomically(log_path, log.dump(2) + "\n");
  log_info("merged {} parts ({} spp) into {}, {}, {}", parts.size(), first.spp, output, png, log_path);
  if (film.aov_events()) log_event_layers(output);
  if (!first.learns.empty())
    log_info("each part learned {} on its own: the merged image is unbiased but is not the image one process "
             "renders (its later samples would use what all earlier ones taught)",
             learned(first));
  if (film.dropped.load() > 0) log_warning("{} non-finite samples were dropped", film.dropped.load());
  return 0;
}

}  // namespace theia
