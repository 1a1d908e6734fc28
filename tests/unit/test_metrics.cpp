#include "core/metrics.h"

#include "app/diff.h"
#include "core/image.h"
#include "core/log.h"
#include "tests/test_util.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>
#include <unistd.h>

namespace theia {
namespace {

namespace fs = std::filesystem;

ImageBuffer rgb_image(int w, int h, const std::vector<float>& values) {
  ImageBuffer img(w, h, {"R", "G", "B"});
  EXPECT_EQ(values.size(), img.data.size());
  img.data = values;
  return img;
}

TEST(Metrics, HandComputedTwoPixelExample) {
  // Pixel 0: reference 1, test differs by 1 in R.  Pixel 1: reference 0, test 0.1 in B.
  ImageBuffer r = rgb_image(2, 1, {1, 1, 1, 0, 0, 0});
  ImageBuffer x = rgb_image(2, 1, {2, 1, 1, 0, 0, 0.1f});
  double b = double(0.1f);
  EXPECT_NEAR(rel_mse(x, r), (1.0 / 1.01 + b * b / 0.01) / 6.0, 1e-12);
  EXPECT_NEAR(rmse(x, r), std::sqrt((1.0 + b * b) / 6.0), 1e-12);
  EXPECT_NEAR(mape(x, r), (1.0 / 1.01 + b / 0.01) / 6.0, 1e-12);
  EXPECT_EQ(rel_mse(r, r), 0.0);
  EXPECT_EQ(rmse(r, r), 0.0);
  EXPECT_EQ(mape(r, r), 0.0);
  // Not symmetric: the reference sets the scale.
  EXPECT_NE(rel_mse(r, x), rel_mse(x, r));
}

TEST(Metrics, UsesChannelsNamedRGBElseTheFirstThree) {
  ImageBuffer r = rgb_image(1, 1, {1, 2, 3});
  ImageBuffer x(1, 1, {"A", "B", "G", "R", "depth.Z"});
  x.data = {100, 3, 2, 1, -50};  // identical RGB, garbage elsewhere
  EXPECT_EQ(rel_mse(x, r), 0.0);
  EXPECT_EQ(channel_mean_deviation(x, r), 0.0);
  ImageBuffer unnamed(1, 1, {"X", "Y", "Z", "W"});
  unnamed.data = {1, 2, 4, 100};
  EXPECT_NEAR(rmse(unnamed, r), std::sqrt(1.0 / 3.0), 1e-12);
}

TEST(Metrics, MismatchedImagesThrow) {
  ImageBuffer a(2, 2, {"R", "G", "B"}), b(2, 3, {"R", "G", "B"}), grey(2, 2, {"Y"});
  EXPECT_THROW(rel_mse(a, b), Error);
  EXPECT_THROW(rmse(a, b), Error);
  EXPECT_THROW(mape(a, b), Error);
  EXPECT_THROW(block_rel_mse(a, b), Error);
  EXPECT_THROW(channel_mean_deviation(a, b), Error);
  EXPECT_THROW(rel_mse(a, grey), Error);
  EXPECT_THROW(block_rel_mse(a, a, 0), Error);
}

TEST(Metrics, BlockRelMseRemovesZeroMeanNoiseButKeepsBias) {
  const int n = 16;
  ImageBuffer r(n, n, {"R", "G", "B"}, 0.5f);
  ImageBuffer noisy = r, biased = r;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      for (int c = 0; c < 3; ++c) {
        noisy.at(x, y, c) += ((x + y) % 2 == 0 ? 0.125f : -0.125f);  // zero mean over any 2x2 tile
        biased.at(x, y, c) *= 1.25f;
      }
  EXPECT_NEAR(rel_mse(noisy, r), 0.125 * 0.125 / 0.26, 1e-12);
  EXPECT_NEAR(block_rel_mse(noisy, r, 8), 0.0, 1e-14);
  EXPECT_NEAR(block_rel_mse(noisy, r, 2), 0.0, 1e-14);
  EXPECT_NEAR(block_rel_mse(noisy, r, 1), rel_mse(noisy, r), 1e-14);
  EXPECT_NEAR(block_rel_mse(biased, r, 8), 0.125 * 0.125 / 0.26, 1e-12);

  // Partial tiles at the edge average the pixels they have: 3x1 grey with
  // block 2 gives tiles {1, 3} -> 2 and {5} -> 5 against a reference of 1.
  ImageBuffer ref(3, 1, {"R", "G", "B"}, 1.0f);
  ImageBuffer x = rgb_image(3, 1, {1, 1, 1, 3, 3, 3, 5, 5, 5});
  EXPECT_NEAR(block_rel_mse(x, ref, 2), (1.0 / 1.01 + 16.0 / 1.01) / 2.0, 1e-12);
}

TEST(Metrics, ChannelMeanDeviationIsTheWorstChannel) {
  ImageBuffer r = rgb_image(2, 1, {1, 1, 1, 1, 1, 1});
  ImageBuffer x = rgb_image(2, 1, {1.2f, 1, 0.7f, 1.0f, 1, 0.9f});  // means 1.1, 1, 0.8
  EXPECT_NEAR(channel_mean_deviation(x, r), 0.2, 1e-6);
  std::vector<double> ratios = channel_mean_ratios(x, r);
  ASSERT_EQ(ratios.size(), 3u);
  EXPECT_NEAR(ratios[0], 1.1, 1e-6);  // signed: brighter in R, darker in B
  EXPECT_NEAR(ratios[1], 1.0, 1e-6);
  EXPECT_NEAR(ratios[2], 0.8, 1e-6);
  ImageBuffer black(2, 1, {"R", "G", "B"}, 0.0f);
  EXPECT_EQ(channel_mean_deviation(black, black), 0.0);
  EXPECT_EQ(channel_mean_ratios(black, black), std::vector<double>(3, 1.0));
  EXPECT_EQ(channel_mean_deviation(x, black), std::numeric_limits<double>::infinity());
  EXPECT_EQ(channel_mean_ratios(x, black)[0], std::numeric_limits<double>::infinity());
  ImageBuffer negative = rgb_image(2, 1, {-1, -1, -1, 0, 0, 0});
  EXPECT_EQ(channel_mean_ratios(negative, black)[2], -std::numeric_limits<double>::infinity());

  ErrorMetrics m = compute_error_metrics(x, r, 1);
  EXPECT_EQ(m.rel_mse, rel_mse(x, r));
  EXPECT_EQ(m.rmse, rmse(x, r));
  EXPECT_EQ(m.mape, mape(x, r));
  EXPECT_EQ(m.block_rel_mse, block_rel_mse(x, r, 1));
  EXPECT_EQ(m.channel_mean_deviation, channel_mean_deviation(x, r));
}

TEST(Metrics, NonFiniteTestValuesAreNotHidden) {
  ImageBuffer r = rgb_image(1, 1, {1, 1, 1});
  ImageBuffer x = rgb_image(1, 1, {std::nanf(""), 1, 1});
  EXPECT_TRUE(std::isnan(rel_mse(x, r)));
  EXPECT_TRUE(std::isnan(channel_mean_deviation(x, r)));
  ImageBuffer black(1, 1, {"R", "G", "B"}, 0.0f);
  EXPECT_TRUE(std::isnan(channel_mean_ratios(x, black)[0]));
}

TEST(Metrics, PerPixelRelativeError) {
  ImageBuffer r = rgb_image(2, 1, {1, 1, 1, 0, 0, 0});
  ImageBuffer x = rgb_image(2, 1, {2, 1, 1, 0, 0, 0});
  std::vector<float> e = per_pixel_rel_error(x, r);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_NEAR(e[0], (1.0 / 1.01) / 3.0, 1e-7);
  EXPECT_EQ(e[1], 0.0f);
}

// A bias confined to one region shows as the worst tile, with the bias in its
// per-channel mean ratio; noise elsewhere ranks below it.
TEST(Metrics, WorstTilesPointAtTheBiasedRegion) {
  ImageBuffer ref(96, 64, {"R", "G", "B"}, 0.5f);
  ImageBuffer test = ref;
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 96; ++x) test.at(x, y, 0) += ((x * 7 + y * 13) % 5 - 2) * 0.002f;  // small noise
  for (int y = 32; y < 64; ++y)
    for (int x = 64; x < 96; ++x) test.at(x, y, 2) *= 1.2f;  // a blue bias in the bottom-right tile
  std::vector<TileError> tiles = worst_tiles(test, ref, 32, 3);
  ASSERT_EQ(tiles.size(), 3u);
  EXPECT_EQ(tiles[0].x0, 64);
  EXPECT_EQ(tiles[0].y0, 32);
  EXPECT_EQ(tiles[0].x1, 96);
  EXPECT_NEAR(tiles[0].mean_ratio[2], 1.2, 1e-6);
  EXPECT_NEAR(tiles[0].mean_ratio[1], 1.0, 1e-9);
  EXPECT_GT(tiles[0].rel_mse, 10.0 * tiles[1].rel_mse);
  EXPECT_GE(tiles[1].rel_mse, tiles[2].rel_mse);
  // Partial tiles at the border are measured over the pixels they have.
  std::vector<TileError> all = worst_tiles(test, ref, 40, -1);
  EXPECT_EQ(all.size(), 6u);
  double weighted = 0.0;
  for (const TileError& t : all) weighted += t.rel_mse * (t.x1 - t.x0) * (t.y1 - t.y0);
  EXPECT_NEAR(weighted / (96.0 * 64.0), rel_mse(test, ref), 1e-9);
}

TEST(DiffColormap, InfernoEndpointsAndMonotoneLightness) {
  // matplotlib: inferno(0) = (0.0015, 0.0005, 0.0139), inferno(1) = (0.9884, 0.9984, 0.6449).
  RGB lo = inferno_colormap(0.0f), hi = inferno_colormap(1.0f);
  // The polynomial fit is within 0.015 of the table.
  EXPECT_NEAR(lo.x, 0.0015f, 0.015f);
  EXPECT_NEAR(lo.y, 0.0005f, 0.015f);
  EXPECT_NEAR(lo.z, 0.0139f, 0.015f);
  EXPECT_NEAR(hi.x, 0.9884f, 0.015f);
  EXPECT_NEAR(hi.y, 0.9984f, 0.015f);
  EXPECT_NEAR(hi.z, 0.6449f, 0.015f);
  // Mid-map: inferno(0.5) = (0.7352, 0.2152, 0.3300).
  RGB mid = inferno_colormap(0.5f);
  EXPECT_NEAR(mid.x, 0.7352f, 0.015f);
  EXPECT_NEAR(mid.y, 0.2152f, 0.015f);
  EXPECT_NEAR(mid.z, 0.3300f, 0.015f);
  EXPECT_EQ(inferno_colormap(-3.0f), lo);
  EXPECT_EQ(inferno_colormap(7.0f), hi);
  float prev = -1.0f;
  for (int i = 0; i <= 32; ++i) {
    float l = luminance(inferno_colormap(float(i) / 32.0f));
    EXPECT_GT(l, prev) << i;
    prev = l;
  }
}

class DiffFiles : public theia::test::TempDirTest {
 protected:
};

TEST_F(DiffFiles, PrintsEveryMetricAndWritesTheErrorImage) {
  ImageBuffer ref(4, 2, {"R", "G", "B", "A"}, 0.5f);
  ImageBuffer test = ref;
  test.at(3, 1, 0) = 1.5f;   // the worst pixel
  test.at(1, 0, 1) = 0.51f;  // a middling error
  test.at(2, 0, 2) = 0.501f; // the smallest non-zero error: bottom of the range
  write_exr(file("test.exr"), test);
  write_exr(file("ref.exr"), ref);

  ::testing::internal::CaptureStdout();
  int rc = run_diff(file("test.exr"), file("ref.exr"), file("err.png"));
  std::string out = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(rc, 0);

  std::map<std::string, double> values;
  std::istringstream all(out);
  std::string line, name;
  int tile_lines = 0;
  while (std::getline(all, line)) {
    std::istringstream lines(line);
    lines >> name;
    if (name == "worst") continue;  // the tile report's header
    if (name == "tile") {
      int x0, y0, x1, y1;
      double rel;
      lines >> x0 >> y0 >> x1 >> y1 >> rel;
      EXPECT_EQ(x1 - x0, 4);  // the whole 4x2 image is one 32x32 tile
      EXPECT_NEAR(rel, rel_mse(test, ref), 1e-5 * rel_mse(test, ref));  // printed to 6 digits
      ++tile_lines;
      continue;
    }
    if (name == "channel_mean_ratio") {
      std::vector<double> expected = channel_mean_ratios(test, ref);
      for (double e : expected) {
        double printed = 0.0;
        lines >> printed;
        EXPECT_NEAR(printed, e, 1e-8) << out;
      }
      EXPECT_NE(expected[0], 1.0);  // the test image is brighter in R: the line must show it
      continue;
    }
    if (name == "error_image") {
      std::string path, label;
      double lo, hi;
      lines >> path >> label >> lo >> hi;
      EXPECT_EQ(path, file("err.png"));
      EXPECT_EQ(label, "log10_rel_error_range");
      EXPECT_LT(lo, hi);
      values["range_hi"] = hi;
      continue;
    }
    lines >> values[name];
  }
  EXPECT_NEAR(values["relMSE"], rel_mse(test, ref), 1e-6 * rel_mse(test, ref)) << out;
  EXPECT_NEAR(values["RMSE"], rmse(test, ref), 1e-6 * rmse(test, ref)) << out;
  EXPECT_NEAR(values["MAPE"], mape(test, ref), 1e-6 * mape(test, ref)) << out;
  EXPECT_NEAR(values["block_relMSE"], block_rel_mse(test, ref), 1e-6 * block_rel_mse(test, ref)) << out;
  EXPECT_NEAR(values["channel_mean_deviation"], channel_mean_deviation(test, ref), 1e-6) << out;
  EXPECT_NEAR(values["range_hi"], std::log10((1.0 / 0.51) / 3.0), 1e-3) << out;
  EXPECT_EQ(tile_lines, 1) << out;

  ImageBuffer err = read_image_file(file("err.png"));
  ASSERT_EQ(err.width, 4);
  ASSERT_EQ(err.height, 2);
  ASSERT_EQ(err.num_channels(), 3);
  // Exact pixels are the bottom of the map (near black), the worst the top (yellow).
  RGB top = inferno_colormap(1.0f), bottom = inferno_colormap(0.0f);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(err.at(3, 1, c), top[c], 1.0f / 255.0f) << c;
    EXPECT_NEAR(err.at(0, 0, c), bottom[c], 1.0f / 255.0f) << c;
  }
  EXPECT_GT(luminance(RGB(err.at(1, 0, 0), err.at(1, 0, 1), err.at(1, 0, 2))), luminance(bottom));
  EXPECT_FALSE(fs::exists(file("err.png.tmp")));
}

TEST_F(DiffFiles, MismatchedSizesAndMissingFilesThrow) {
  write_exr(file("a.exr"), ImageBuffer(4, 2, {"R", "G", "B"}, 1.0f));
  write_exr(file("b.exr"), ImageBuffer(2, 4, {"R", "G", "B"}, 1.0f));
  EXPECT_THROW(run_diff(file("a.exr"), file("b.exr"), ""), Error);
  EXPECT_THROW(run_diff(file("a.exr"), file("none.exr"), ""), Error);
}

}  // namespace
}  // namespace theia
