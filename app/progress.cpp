#include "app/progress.h"

#include <cstdio>
#include <string>

namespace theia {

ProgressBar::ProgressBar(bool enabled)
    : enabled_(enabled), start_(std::chrono::steady_clock::now()), last_(start_ - std::chrono::seconds(1)) {}

void ProgressBar::update(double fraction, uint64_t rays) {
  if (!enabled_) return;
  auto now = std::chrono::steady_clock::now();
  if (fraction < 1.0 && now - last_ < std::chrono::milliseconds(250)) return;
  last_ = now;
  double elapsed = std::chrono::duration<double>(now - start_).count();
  double eta = fraction > 0.0 ? elapsed * (1.0 - fraction) / fraction : 0.0;
  constexpr int kWidth = 30;
  int filled = int(fraction * kWidth);
  std::string bar(size_t(filled), '=');
  bar.resize(kWidth, ' ');
  std::fprintf(stderr, "\r[%s] %5.1f%%  %6.2f Mrays/s  ETA %5.0fs ", bar.c_str(), fraction * 100.0,
               elapsed > 0 ? double(rays) / elapsed * 1e-6 : 0.0, eta);
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  if (enabled_ && drawn_) std::fprintf(stderr, "\n");
}

}  // namespace theia
