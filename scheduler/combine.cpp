#include "scheduler/combine.h"

#include "core/color.h"
#include "core/log.h"

#include <algorithm>

#include <cmath>

namespace theia {

Combination parse_combination(const std::string& name) {
  if (name == "equal") return Combination::Equal;
  if (name == "inverse-variance") return Combination::InverseVariance;
  throw_error("--combine {}: expected equal or inverse-variance", name);
}

const char* combination_name(Combination c) { return c == Combination::Equal ? "equal" : "inverse-variance"; }

std::vector<float> half_buffer_variance(const Film& f) {
  std::vector<float> var(f.pixel_count(), -1.0f);
  const std::vector<float>* sum[3] = {&f.r, &f.g, &f.b};
  const std::vector<float>* odd[3] = {&f.r_odd, &f.g_odd, &f.b_odd};
  for (size_t i = 0; i < var.size(); ++i) {
    float w_odd = f.weight_odd[i], w_even = f.weight[i] - w_odd;
    if (!(w_odd > 0.0f) || !(w_even > 0.0f)) continue;
    float v = 0.0f;
    for (int c = 0; c < 3; ++c) {
      float o = (*odd[c])[i] / w_odd, e = ((*sum[c])[i] - (*odd[c])[i]) / w_even;
      v += 0.25f * (e - o) * (e - o);
    }
    var[i] = v / 3.0f;
  }
  return var;
}

RelativeVariance relative_variance(const Film& it, const std::vector<float>& var, const Film* prior) {
  auto pixel_mean = [](const Film& f, size_t i) {
    return (double(f.r[i]) + double(f.g[i]) + double(f.b[i])) / (3.0 * double(f.weight[i]));
  };
  std::vector<double> rel;
  size_t sampled = 0;
  for (size_t i = 0; i < var.size(); ++i) {
    if (it.weight[i] > 0.0f) ++sampled;
    if (!(var[i] >= 0.0f)) continue;
    const double mean = prior && prior->weight[i] > 0.0f ? pixel_mean(*prior, i) : pixel_mean(it, i);
    rel.push_back(double(var[i]) * double(it.weight[i]) / (mean * mean + 0.01));
  }
  if (rel.empty() || rel.size() * 2 < sampled) return {};
  RelativeVariance out;
  double sum = 0.0;
  for (double r : rel) sum += r;
  out.full = sum / double(rel.size());
  const size_t keep = rel.size() - rel.size() / 100;
  std::nth_element(rel.begin(), rel.begin() + std::ptrdiff_t(keep - 1), rel.end());
  sum = 0.0;
  for (size_t i = 0; i < keep; ++i) sum += rel[i];
  out.robust = sum / double(keep);
  return out;
}

nlohmann::json CombinationChoice::log() const {
  return {{"used", combination_name(used)},
          {"why", why},
          {"estimated_variance", {{"equal", equal_variance}, {"inverse_variance", weighted_variance}}},
          {"window_spp", {window_begin, window_end}},
          {"pooled_spp", {pooled_begin, pooled_end}}};
}

// The per-sample variance of the iteration, averaged over the pixels that
// have a half-buffer estimate: Var[pixel estimate] * W = sigma^2 per unit of
// filter weight.  < 0 when too few pixels have one (1-spp iterations).
double per_sample_variance(const Film& it, const std::vector<float>& var) {
  double sum = 0.0;
  size_t known = 0, sampled = 0;
  for (size_t i = 0; i < var.size(); ++i) {
    if (it.weight[i] > 0.0f) ++sampled;
    if (var[i] >= 0.0f) {
      sum += double(var[i]) * double(it.weight[i]);
      ++known;
    }
  }
  return known > 0 && known * 2 >= sampled ? sum / double(known) : -1.0;
}

namespace {

void merge(WeightedRun& into, const WeightedRun& later) {
  into.spp_end = later.spp_end;
  for (size_t i = 0; i < into.sum.size(); ++i) into.sum[i] += later.sum[i];
  for (size_t i = 0; i < into.weight.size(); ++i) {
    into.weight[i] += later.weight[i];
    into.variance[i] += later.variance[i];
  }
}

// Adds iteration `it` [spp_begin, spp_end) to `run` with weight lambda per
// sample; s2 is the iteration's per-sample variance, for the pixels without
// a half-buffer estimate (their v = s2 / W).
void add_weighted(WeightedRun& run, const Film& it, const std::vector<float>& var, double s2, float lambda,
                  uint32_t spp_begin, uint32_t spp_end) {
  const size_t n = it.pixel_count();
  if (run.empty()) run = {spp_begin, spp_begin, std::vector<float>(3 * n), std::vector<float>(n), std::vector<float>(n)};
  run.spp_end = spp_end;
  for (size_t i = 0; i < n; ++i) {
    const float wi = it.weight[i];
    run.sum[3 * i] += lambda * it.r[i];
    run.sum[3 * i + 1] += lambda * it.g[i];
    run.sum[3 * i + 2] += lambda * it.b[i];
    run.weight[i] += lambda * wi;
    run.variance[i] += var[i] >= 0.0f ? lambda * lambda * wi * wi * var[i] : float(double(lambda) * lambda * wi * s2);
  }
}

// The one weight of the settled run, 1 / its per-sample variance pooled over
// every pixel it reached: each pixel's Var[estimate] * W = variance / W.
// 0 when it has none (empty, or noiseless).
double pooled_lambda(const WeightedRun& run) {
  double sum = 0.0;
  size_t reached = 0;
  for (size_t i = 0; i < run.weight.size(); ++i)
    if (run.weight[i] > 0.0f) {
      sum += double(run.variance[i]) / double(run.weight[i]);
      ++reached;
    }
  const double s2 = reached > 0 ? sum / double(reached) : 0.0;
  return s2 > 0.0 && std::isfinite(s2) ? 1.0 / s2 : 0.0;
}

}  // namespace

void ImageAccumulator::fold(const Film& it, uint32_t spp_begin, uint32_t spp_end, uint32_t settled_from) {
  total.add(it);
  if (combination == Combination::Equal) return;

  // Runs that ended before the window leave it (the boundary only moves forward).
  // settled_from is known from the iteration that begins there on, and every
  // boundary before lay at or before it: the boundary still only moves forward.
  const uint32_t boundary = window > 0 ? std::min(spp_end > window ? spp_end - window : 0, settled_from) : 0;
  std::erase_if(runs, [&](const WeightedRun& r) { return r.spp_end <= boundary; });

  // An unsettled iteration of a few spp (a schedule's first) has too noisy a
  // variance estimate to weigh it by: one that happened to miss the bright,
  // rare paths gets a large weight and pulls the image down (material-testball
  // with --guiding-auto at 30 s: mean -1.1%, MAPE 4x).  Leaving it out by its
  // size alone keeps the weighting unbiased.  A settled one (a time limit's
  // last) joins the pooled run, whose weight it barely moves.
  const bool settled_now = spp_begin >= settled_from;
  if (!settled_now && spp_end - spp_begin < kMinWeightedSpp) {
    ++skipped;
    return;
  }
  const std::vector<float> var = half_buffer_variance(it);
  const double s2 = per_sample_variance(it, var);
  if (settled_now && s2 >= 0.0 && std::isfinite(s2)) {
    add_weighted(settled, it, var, s2, 1.0f, spp_begin, spp_end);
    return;
  }
  if (!(s2 > 0.0) || !std::isfinite(s2)) {  // unknown, or noiseless: nothing to weight by
    ++skipped;
    return;
  }
  WeightedRun run;
  add_weighted(run, it, var, s2, float(1.0 / s2), spp_begin, spp_end);
  runs.push_back(std::move(run));
  if (runs.size() > kMaxBlocks) {
    // Merge the adjacent pair with the fewest samples (the oldest of equals).
    size_t best = 0;
    for (size_t k = 1; k + 1 < runs.size(); ++k)
      if (runs[k + 1].spp_end - runs[k].spp_begin < runs[best + 1].spp_end - runs[best].spp_begin) best = k;
    merge(runs[best], runs[best + 1]);
    runs.erase(runs.begin() + std::ptrdiff_t(best) + 1);
  }
}

CombinationChoice ImageAccumulator::choice() const {
  CombinationChoice c;
  resolve(&c);
  return c;
}

ImageBuffer ImageAccumulator::resolve() const { return resolve(nullptr); }

ImageBuffer ImageAccumulator::resolve(CombinationChoice* choice) const {
  ImageBuffer out = resolve_film(total);
  CombinationChoice local;
  CombinationChoice& c = choice ? *choice : local;
  if (combination == Combination::Equal) {
    c.why = "asked for (--combine equal)";
    return out;
  }
  const double settled_lambda = pooled_lambda(settled);
  if (runs.empty() && settled_lambda == 0.0) {
    c.why = "no iteration in the window has a variance estimate";
    return out;
  }
  c.window_begin = runs.empty() ? settled.spp_begin : runs.front().spp_begin;
  c.window_end = settled_lambda > 0.0 ? settled.spp_end : runs.back().spp_end;
  if (settled_lambda > 0.0) {
    c.pooled_begin = settled.spp_begin;
    c.pooled_end = settled.spp_end;
  }

  // Both images and their estimated variances, pixel by pixel.
  const size_t n = total.pixel_count(), nc = out.channels.size();
  const std::vector<float> equal_var = half_buffer_variance(total);
  std::vector<float> rgb(3 * n);
  double equal_sum = 0.0, weighted_sum = 0.0;
  size_t compared = 0;
  for (size_t i = 0; i < n; ++i) {
    double s[3] = {0, 0, 0}, w = 0, v = 0;
    for (const WeightedRun& r : runs) {
      for (int ch = 0; ch < 3; ++ch) s[ch] += r.sum[3 * i + size_t(ch)];
      w += r.weight[i];
      v += r.variance[i];
    }
    if (settled_lambda > 0.0) {
      for (int ch = 0; ch < 3; ++ch) s[ch] += settled_lambda * settled.sum[3 * i + size_t(ch)];
      w += settled_lambda * settled.weight[i];
      v += settled_lambda * settled_lambda * settled.variance[i];
    }
    if (w == 0.0) {  // not reached by the window: the equal image's pixel
      for (int ch = 0; ch < 3; ++ch) rgb[3 * i + size_t(ch)] = out.data[i * nc + size_t(ch)];
      if (equal_var[i] >= 0.0f) {
        equal_sum += equal_var[i];
        weighted_sum += equal_var[i];
        ++compared;
      }
      continue;
    }
    RGB p = working_to_srgb(RGB(resolve_sum(float(s[0]), float(w)), resolve_sum(float(s[1]), float(w)),
                                resolve_sum(float(s[2]), float(w))));
    for (int ch = 0; ch < 3; ++ch) rgb[3 * i + size_t(ch)] = p[ch];
    if (equal_var[i] >= 0.0f) {
      equal_sum += equal_var[i];
      weighted_sum += v / (w * w);
      ++compared;
    }
  }
  if (compared == 0) {
    c.why = "no pixel has a variance estimate";
    return out;
  }
  c.equal_variance = equal_sum / double(compared);
  c.weighted_variance = weighted_sum / double(compared);
  if (!(c.weighted_variance < c.equal_variance)) {
    c.why = "equal weights are estimated to be no noisier";
    return out;
  }
  c.used = Combination::InverseVariance;
  c.why = "estimated to be less noisy than equal weights";
  for (size_t i = 0; i < n; ++i)
    for (size_t ch = 0; ch < 3; ++ch) out.data[i * nc + ch] = rgb[3 * i + ch];
  return out;
}

}  // namespace theia
