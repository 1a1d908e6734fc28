// What the light-sampler e2e tests share: a small street to render and the
// check that a sampler is unbiased on it (it converges to what power
// sampling converges to).
#pragma once

#include "core/metrics.h"
#include "render_helpers.h"
#include "tests/street_scene.h"

#include <gtest/gtest.h>

#include <string>

namespace theia::test {

// 6 x 6 emitters each side of the wall, a camera looking at the left side, a dim sky.
inline std::string lit_street() {
  return street_scene(6, [](int k) { return 0.5f + float((k * 7) % 5); }, true, false,
                      "LookAt -6 3 -10  0 1 0  0 1 0\n", 0.3f);
}

// The street at 512 spp with `sampler` (seed 1) against power sampling (seed
// 0): image means within 1%, no 8x8 block biased, nothing dropped.  Returns
// the sampler's render, for its log.
inline RenderResult expect_converges_to_power(const std::string& sampler) {
  Scene scene = load_test_scene(lit_street());
  RenderConfig power = quick_config(512), other = quick_config(512);
  power.light_sampler = "power";
  other.light_sampler = sampler;
  other.seed = 1;
  RenderResult a = render_scene(scene, power), b = render_scene(scene, other);
  EXPECT_EQ(b.log["light_sampler"]["name"], sampler);
  const RGB ma = image_mean(a.image), mb = image_mean(b.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mb[c], ma[c], 0.01 * ma[c]) << "channel " << c;
  EXPECT_LT(compute_error_metrics(b.image, a.image).block_rel_mse, 2e-3);
  EXPECT_EQ(b.log["dropped_samples"].get<uint64_t>(), 0u);
  return b;
}

}  // namespace theia::test
