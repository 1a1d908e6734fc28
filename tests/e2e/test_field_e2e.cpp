// render --save-field and `theia field stats|image` end to end: the file a
// guided render writes agrees with the recorder's and the tree's counts in the
// log, saving it changes no pixel, and the commands read it (or name what is wrong).
#include "core/log.h"
#include "guiding/field_file.h"
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>

using namespace theia;
using namespace theia::test;

namespace {

const std::string kCornell = std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt";

Scene small_cornell() {
  Scene s = load_test_scene_file(kCornell);
  s.film.width = s.film.height = 24;
  return s;
}

RenderConfig guided(int spp) {
  RenderConfig c = quick_config(spp);
  c.guiding.enabled = OnOffAuto::On;
  c.threads = 2;
  return c;
}

}  // namespace

TEST(FieldSave, EveryIterationsSnapshotAgreesWithTheLogAndChangesNoPixel) {
  TempDir tmp("theia_field_save");
  const Scene scene = small_cornell();
  RenderConfig c = guided(8);
  // Bit for bit, so on one thread: across threads the film's sums (and the
  // recorder's) follow the scheduler's order, which design.md allows to move
  // last bits between any two runs (Determinism.IndependentOfThreadCount).
  c.threads = 1;
  const RenderResult plain = render_scene(scene, c);
  c.save_field = tmp.file("f.field");
  c.save_field_every_iteration = true;
  const RenderResult saved = render_scene(scene, c);
  EXPECT_EQ(plain.image.data, saved.image.data) << "saving the field must not change the render";

  const FieldFile f = load_field(c.save_field);
  const nlohmann::json& log = saved.log;
  ASSERT_EQ(f.snapshots.size(), log["scheduler"]["iterations"].size());
  double handed = 0.0;
  for (const FieldSnapshot& s : f.snapshots)
    for (const auto& [key, value] : s.summary)
      if (key == "samples_recorded" || key == "samples_dropped") handed += value;
  EXPECT_EQ(handed, log["recorder"]["samples"].get<double>()) << "every sample the recorder handed over, once";
  const FieldSnapshot& last = f.snapshots.back();
  EXPECT_EQ(last.leaves.size(), log["guiding"]["spatial_leaves"].get<size_t>());
  EXPECT_EQ(last.spp, 8u);
  EXPECT_EQ(f.wireframe.p.size(), 3u * f.wireframe.scene_triangles) << "the Cornell box is small: every triangle";
  EXPECT_EQ(log["guiding"]["field_file"]["snapshots"].get<size_t>(), f.snapshots.size());
}

TEST(FieldSave, NeedsGuiding) {
  RenderConfig c = quick_config(1);
  c.save_field = "x.field";
  EXPECT_THROW(check_config(c), Error);
  c.save_field.clear();
  c.save_field_every_iteration = true;
  c.guiding.enabled = OnOffAuto::On;
  EXPECT_THROW(check_config(c), Error);
}

TEST(FieldCommands, StatsAndImageReadTheFileAndNameABadOne) {
  TempDir tmp("theia_field_cmd");
  RenderConfig c = guided(4);
  c.save_field = tmp.file("f.field");
  render_scene(small_cornell(), c);
  RunResult r = run_theia("field stats --json " + c.save_field);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  const FieldFile f = load_field(c.save_field);
  EXPECT_EQ(j["leaves"].get<size_t>(), f.snapshots.back().leaves.size());
  EXPECT_EQ(j["per_leaf"]["samples"].size(), f.snapshots.back().leaves.size());
  EXPECT_EQ(j["columns"]["samples_iteration"]["sum"].get<double>(), j["summary"]["samples_recorded"].get<double>());

  r = run_theia("field image " + c.save_field + " --point 0 1 0 --width 64 -o " + tmp.file("d.png"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const ImageBuffer png = read_image_file(tmp.file("d.png"));
  EXPECT_EQ(png.width, 64);
  EXPECT_EQ(png.height, 32);

  static const char kBad[] = "THEIAFLD\x01\0\0\0garbage that is no field";
  tmp.write("bad.field", std::string(kBad, sizeof(kBad) - 1));
  r = run_theia("field stats " + tmp.file("bad.field"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("bad.field: field file corrupt: checksum"), std::string::npos) << r.output;
  r = run_theia("render " + kCornell + " --guiding --spp 1 -o " + tmp.file("x.exr") + " --save-field " +
                tmp.file("missing/f.field"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--save-field " + tmp.file("missing/f.field") + ": the directory"), std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(tmp.file("x.exr"))) << "refused before rendering";
  r = run_theia("field image " + c.save_field + " --point 0 0 0 --iteration 99 -o " + tmp.file("x.png"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("no snapshot of iteration 99"), std::string::npos) << r.output;
}

// --guiding-field vmm with --save-field: each leaf carries its region's
// mixture (and no quadtree: the mixture is what the renderer samples), the
// stats list the lobes, and `field image` draws the mixture's own pdf seen
// from the point (parallax included).  Saving changes no pixel.
TEST(FieldCommands, MixtureFieldIsSavedListedAndImaged) {
  TempDir tmp("theia_field_vmm");
  const Scene scene = small_cornell();
  RenderConfig c = guided(8);
  c.guiding.field = "vmm";
  c.threads = 1;
  const RenderResult plain = render_scene(scene, c);
  c.save_field = tmp.file("f.field");
  const RenderResult saved = render_scene(scene, c);
  EXPECT_EQ(plain.image.data, saved.image.data) << "saving the field must not change the render";

  const FieldFile f = load_field(c.save_field);
  const FieldSnapshot& s = f.snapshots.back();
  const int active = s.column("vmm_active_lobes"), fitted = s.column("vmm_fitted");
  ASSERT_GE(active, 0);
  ASSERT_GE(fitted, 0);
  std::vector<size_t> mixtures;
  for (size_t l = 0; l < s.leaves.size(); ++l) {
    EXPECT_TRUE(s.leaves[l].quadtree.empty()) << l;
    EXPECT_EQ(s.leaves[l].lobes.empty(), s.value(l, fitted) == 0.0) << l;
    if (s.leaves[l].lobes.empty()) continue;
    mixtures.push_back(l);
    EXPECT_EQ(s.leaves[l].lobes.size(), size_t(kVMMLobes));
    EXPECT_GE(s.value(l, active), 1.0);
    EXPECT_LE(s.value(l, active), double(kVMMLobes));
    EXPECT_GT(s.value(l, s.column("vmm_kappa_max")), 0.0);
  }
  ASSERT_GT(mixtures.size(), 1u);
  EXPECT_EQ(saved.log["guiding"]["vmm"]["fitted_regions"].get<size_t>(), mixtures.size());

  RunResult r = run_theia("field stats --json " + c.save_field);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  ASSERT_EQ(j["mixtures"].size(), s.leaves.size());
  const size_t leaf = mixtures.front();
  const nlohmann::json& m = j["mixtures"][leaf];
  ASSERT_EQ(m["lobes"].size(), size_t(kVMMLobes));
  EXPECT_EQ(m["lobes"][0]["kappa"].get<float>(), s.leaves[leaf].lobes[0].kappa);
  EXPECT_EQ(m["lobes"][7]["weight"].get<float>(), s.leaves[leaf].lobes[7].weight);
  r = run_theia("field stats " + c.save_field + " --leaf " + std::to_string(leaf));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("mixture field: " + std::to_string(mixtures.size()) + " of"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("leaf " + std::to_string(leaf) + ": mixture seen from the pivot"), std::string::npos)
      << r.output;

  // The image at a point inside the leaf, off its centre: the brightest pixel is where the mixture's pdf
  // (re-pointed to the point) peaks, pixels three decades below the peak are the darkest, and between
  // them brightness follows the pdf (inferno's green rises with it).
  const Bounds3& box = s.leaves[leaf].box;
  const vec3 p = box.min + vec3(0.3f, 0.6f, 0.4f) * box.diagonal();
  const int width = 64, height = 32;
  r = run_theia(fmt::format("field image {} --point {} {} {} --width {} -o {}", c.save_field, p.x, p.y, p.z, width,
                            tmp.file("m.png")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const ImageBuffer png = read_image_file(tmp.file("m.png"));
  ASSERT_EQ(png.width, width);
  const VMMixture at = vmm_at(
      [&] {
        VMMixture mix;
        std::copy(s.leaves[leaf].lobes.begin(), s.leaves[leaf].lobes.end(), mix.lobes.begin());
        return mix;
      }(),
      s.leaves[leaf].pivot, p);
  std::vector<double> pdf(size_t(width * height));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      pdf[size_t(y * width + x)] = vmm_pdf(
          at, sd_square_to_direction(vec2(float(1.0 - (y + 0.5) / height), float((x + 0.5) / width))));
  const double peak = *std::max_element(pdf.begin(), pdf.end());
  float brightest = -1.0f, darkest = 1e30f;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      brightest = std::max(brightest, pixel_channel(png, x, y, 1)), darkest = std::min(darkest, pixel_channel(png, x, y, 1));
  size_t compared = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double d = pdf[size_t(y * width + x)];
      if (d == peak) {
        EXPECT_EQ(pixel_channel(png, x, y, 1), brightest) << x << " " << y;
        ++compared;
      }
      if (d < 1e-3 * peak) {
        EXPECT_EQ(pixel_channel(png, x, y, 1), darkest) << x << " " << y;
        ++compared;
      }
    }
  EXPECT_GE(compared, 1u);
  EXPECT_GT(brightest, darkest);
  for (int k = 0; k + 1 < width * height; k += 7) {
    const int a = k, b = (k * 131 + 17) % (width * height);
    if (!(pdf[size_t(a)] > 1.3 * pdf[size_t(b)]) || !(pdf[size_t(b)] > 1e-3 * peak)) continue;
    EXPECT_GE(pixel_channel(png, a % width, a / width, 1), pixel_channel(png, b % width, b / width, 1)) << a << " " << b;
    ++compared;
  }
  EXPECT_GT(compared, 10u);
}
