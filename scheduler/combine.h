// Folding per-iteration images into the result.
//
// Equal weighting (the default) sums every iteration's film: each sample
// counts the same, so a guided render is never noisier than an unguided one
// at equal spp (seeds/000 ch. 2 section 6.2).
//
// Inverse-variance weighting (seeds/001 section 10.3, for path guiding, whose
// later iterations are better) gives iteration k a whole-image weight per
// sample, lambda_k = 1 / s_k^2, with s_k^2 its per-sample variance averaged
// over the image (from its half buffers; per-pixel weights would correlate
// with the pixel values and bias them).  A pixel is
//     sum_k lambda_k S_k(p) / sum_k lambda_k W_k(p)
// with S and W the film's sums of w L and of w.  The weight is per sample, not
// per image, so iterations of different sizes, adaptive sampling's uneven
// per-pixel counts and the part of an iteration a time limit stopped combine
// without bias (a pixel an iteration did not reach gets nothing from it), and
// equal lambdas are exactly equal weighting.
//
// The iterations from the one where the estimator settled on (fold's
// `settled_from`: a frozen guiding field) sample one and the same estimator,
// so they share one weight: they are pooled into one unweighted run whose
// variance, estimated from all of their samples, sets that weight when the
// image is resolved.  Weighing each by its own noisy estimate would correlate
// the weights with the images (an iteration that missed the rare bright paths
// is estimated both darker and less noisy, and gets more weight): a bias the
// pooled estimate, from hundreds of spp, all but removes.
//
// By default every iteration with a variance estimate takes part (seeds/001
// 10.3 combines them all: a learning iteration's noise lowers its weight
// rather than removing its samples).  A `window` in spp keeps only the
// iterations in the last that many spp (Mueller 2017 keeps only the last
// iteration, half the samples of a doubling schedule), and never fewer than
// every sample since the estimator settled.  The samples before the window,
// those of iterations without a variance estimate (1 spp) and those of
// unsettled iterations under kMinWeightedSpp are in the equal image only, and
// resolve() uses the inverse-variance image only where it is estimated to be
// less noisy than the equal one (mean over the image of both variance
// estimates, from the same half buffers), so it is never worse than equal
// weights by that estimate; choice() says which it used and why.
//
// Memory: nothing beyond the total with equal weighting; with inverse-
// variance weighting at most kMaxBlocks runs of iterations and the settled
// run, 5 floats per pixel each, whatever the number of iterations (older runs
// are merged, which for the weighted sums is exact; a merged run leaves the
// window when its last sample does, so the window is at least `window` spp).
#pragma once

#include "core/image.h"
#include "wavefront/film.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace theia {

enum class Combination { Equal, InverseVariance };
Combination parse_combination(const std::string& name);  // "equal" | "inverse-variance"
const char* combination_name(Combination c);

// Variance of each pixel's iteration estimate from its two half buffers
// (even and odd samples): ((even - odd) / 2)^2 averaged over R, G, B.  Pixels
// with no sample in one half get -1 (unknown).
std::vector<float> half_buffer_variance(const Film& film);
// The iteration's per-sample variance averaged over the pixels that have a
// half-buffer estimate `var` (Var[pixel estimate] * W); < 0 when too few
// pixels have one (1-spp iterations).
double per_sample_variance(const Film& iteration, const std::vector<float>& var);
// The per-sample relative variance of an iteration, Var * W / (mean^2 +
// 0.01) per pixel (weighted as relMSE weighs errors), averaged over the
// pixels: what an efficiency estimate compares between two iterations.
// `mean` is the pixel's value in `prior` (the iterations before, a stabler
// estimate) where it has samples, else the iteration's own; the iteration's
// own mean would hide a firefly (one sample of value V among n makes mean
// ~ V / n, so the pixel's figure stays near n however large V is).
struct RelativeVariance {
  // The 1% most variable pixels left out: one firefly does not decide it.
  double robust = -1.0;
  // Every pixel: what relMSE sees, fireflies included (noisier).
  double full = -1.0;
  bool known() const { return robust >= 0.0 && full >= 0.0; }
};
// Unknown (both < 0) when too few pixels have a half-buffer estimate.
RelativeVariance relative_variance(const Film& iteration, const std::vector<float>& var, const Film* prior = nullptr);

// Consecutive iterations [spp_begin, spp_end), summed with their weights:
// what the inverse-variance image needs of them.
struct WeightedRun {
  uint32_t spp_begin = 0, spp_end = 0;
  std::vector<float> sum;       // sum_k lambda_k S_k, working-space RGB interleaved
  std::vector<float> weight;    // sum_k lambda_k W_k
  std::vector<float> variance;  // sum_k lambda_k^2 W_k^2 v_k (v_k: the pixel estimate's variance)
  bool empty() const { return spp_end == spp_begin; }
};

// What resolve() uses and why.
struct CombinationChoice {
  Combination used = Combination::Equal;
  std::string why;
  double equal_variance = -1.0;     // mean over pixels of the estimated variance; < 0: not estimated
  double weighted_variance = -1.0;
  uint32_t window_begin = 0, window_end = 0;  // spp of the iterations weighted
  uint32_t pooled_begin = 0, pooled_end = 0;  // spp of the settled iterations weighted as one
  nlohmann::json log() const;
};

struct ImageAccumulator {
  static constexpr size_t kMaxBlocks = 4;
  static constexpr uint32_t kMinWeightedSpp = 8;  // smaller iterations are in the equal image only

  Film total;                      // every iteration summed
  Combination combination;
  uint32_t window;                 // spp; 0: every iteration
  std::vector<WeightedRun> runs;   // inverse-variance only: the runs in the window, oldest first
  // Inverse-variance only: the iterations since the estimator settled, summed
  // with lambda = 1; resolve() weighs the run by one lambda from its pooled
  // variance.  After every run in `runs`; empty until an iteration settles.
  WeightedRun settled;
  uint32_t skipped = 0;            // iterations left out of the weighting (no variance estimate)

  // `aov_events`: the iterations' films have the event planes (Film::aov_events).
  ImageAccumulator(int width, int height, Combination c = Combination::Equal, uint32_t window_spp = 0,
                   bool aov_events = false)
      : total(width, height, aov_events), combination(c), window(window_spp) {}
  // The iteration that rendered samples [spp_begin, spp_end) (all of them, or
  // the part a time limit left).  Samples from `settled_from` on stay in the
  // window whatever its size: from there the estimator no longer changes (a
  // frozen guiding field), so the window's rule, meant to leave out the
  // iterations that were still learning, must not drop any of them.
  void fold(const Film& iteration, uint32_t spp_begin, uint32_t spp_end,
            uint32_t settled_from = std::numeric_limits<uint32_t>::max());
  CombinationChoice choice() const;
  // R G B A albedo.* N.* depth.Z, as resolve_film, with R G B as choice() says.
  ImageBuffer resolve() const;

 private:
  ImageBuffer resolve(CombinationChoice* choice) const;
};

}  // namespace theia
