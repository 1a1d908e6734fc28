#include "scheduler/combine.h"

#include "core/log.h"

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

void ImageAccumulator::fold(const Film& it) {
  total.add(it);
  // Resolved exactly as the output is (linear sRGB, cancelled weights black),
  // so resolve() can mix iteration images into it.
  IterationImage img;
  img.rgb.assign(it.pixel_count() * 3, 0.0f);
  const ImageBuffer resolved = resolve_film(it);
  const size_t nc = resolved.channels.size();
  for (size_t i = 0; i < it.pixel_count(); ++i)
    for (size_t c = 0; c < 3; ++c) img.rgb[3 * i + c] = resolved.data[i * nc + c];
  double sum = 0.0;
  size_t known = 0;
  for (float v : half_buffer_variance(it))
    if (v >= 0.0f) {
      sum += v;
      ++known;
    }
  // Unknown when most pixels have no second half (1-spp iterations).
  img.mean_variance = known * 2 >= it.pixel_count() && known > 0 ? sum / double(known) : -1.0;
  recent.push_back(std::move(img));
  if (recent.size() > kInverseVarianceWindow) recent.pop_front();
}

ImageBuffer ImageAccumulator::resolve(Combination c) const {
  ImageBuffer out = resolve_film(total);
  if (c == Combination::Equal || recent.empty()) return out;
  // Whole-image weights; fall back to equal weighting when a variance is
  // unknown or zero (a noiseless image needs no weighting).
  std::vector<double> w;
  for (const IterationImage& img : recent) {
    if (!(img.mean_variance > 0.0)) return out;
    w.push_back(1.0 / img.mean_variance);
  }
  double wsum = 0.0;
  for (double x : w) wsum += x;
  const size_t nc = out.channels.size();
  for (size_t i = 0; i < out.pixel_count(); ++i)
    for (int ch = 0; ch < 3; ++ch) {
      double v = 0.0;
      for (size_t k = 0; k < recent.size(); ++k) v += w[k] * recent[k].rgb[3 * i + ch];
      out.data[i * nc + ch] = float(v / wsum);
    }
  return out;
}

}  // namespace theia
