// FXAA on the CPU (render/fxaa.hpp). Written after the algorithm of NVIDIA's FXAA whitepaper as VTK's filter
// applies it (its defaults and its endpoint search), so that a picture smoothed here matches one smoothed by VTK to
// a level or two in a few pixels. No library offers it on the CPU; VTK's own runs only as a shader.
//
// Directions follow the texture VTK's filter samples (rows bottom-up): its "north" neighbour is the image's row
// below (y + 1), and ties between directions are broken as that filter breaks them.
#include "render/fxaa.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace vmsim::render {

namespace {

// vtkOpenGLFXAAFilter's defaults.
constexpr float kRelativeContrast = 1.f / 8.f, kHardContrast = 1.f / 16.f;
constexpr float kSubpixelBlendLimit = 3.f / 4.f, kSubpixelContrast = 1.f / 4.f;
constexpr int kSearchSteps = 12;

// The rectangle's pixels as the filter reads them, coordinates clamped to its edges: the original 8-bit colours of
// the rows around the one being smoothed and the lumas of the rows the endpoint search can reach, in rings of rows
// (a few rows' memory, not a copy of the picture: pictures go up to 16384 x 16384).
struct Source {
  static constexpr int kLumaRows = 2 * kSearchSteps + 5;  // rows y - 14 .. y + 14: the search reaches +-12
  static constexpr int kRgbRows = 3;                      // rows y - 1 .. y + 1: the 3 x 3 mean, HC
  int w = 0, h = 0;
  std::vector<std::uint8_t> rgb;  // kRgbRows rows
  std::vector<float> luma;        // kLumaRows rows

  static int ring(int y, int n) { return ((y % n) + n) % n; }
  std::size_t at(int x, int y, int rows) const {
    return static_cast<std::size_t>(ring(std::clamp(y, 0, h - 1), rows)) * static_cast<std::size_t>(w) +
           static_cast<std::size_t>(std::clamp(x, 0, w - 1));
  }
  float l(int x, int y) const { return luma[at(x, y, kLumaRows)]; }
  const std::uint8_t* c(int x, int y) const { return rgb.data() + 3 * at(x, y, kRgbRows); }
};

float to_unit(std::uint8_t v) { return static_cast<float>(v) * (1.f / 255.f); }

std::uint8_t to_byte(float v) { return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.f, 1.f) * 255.f)); }

// One pixel's smoothed colour; false when it stays as it is.
bool smooth_pixel(const Source& s, int x, int y, std::uint8_t out[3]) {
  const float lC = s.l(x, y), lN = s.l(x, y + 1), lS = s.l(x, y - 1), lW = s.l(x - 1, y), lE = s.l(x + 1, y);
  const float lmin = std::min(lC, std::min(std::min(lN, lS), std::min(lW, lE)));
  const float lmax = std::max(lC, std::max(std::max(lN, lS), std::max(lW, lE)));
  const float range = lmax - lmin;
  if (range < std::max(kHardContrast, kRelativeContrast * lmax)) return false;

  const float lNE = s.l(x + 1, y + 1), lSE = s.l(x + 1, y - 1), lNW = s.l(x - 1, y + 1), lSW = s.l(x - 1, y - 1);
  // A lone speck (C far from the mean of its four neighbours) is blended towards its 3 x 3 mean.
  const float sub_range = std::abs(0.25f * (lN + lS + lW + lE) - lC);
  float blend_sub = std::max(0.f, sub_range / range - kSubpixelContrast);
  blend_sub = std::min(kSubpixelBlendLimit, blend_sub * (1.f / (1.f - kSubpixelContrast)));
  float mean[3] = {0, 0, 0};
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const std::uint8_t* p = s.c(x + dx, y + dy);
      for (int k = 0; k < 3; ++k) mean[k] += to_unit(p[k]);
    }
  for (float& m : mean) m *= 1.f / 9.f;

  // Edge direction from the 3 x 3 second differences across rows and across columns.
  const float vert =
      (2.f * std::abs(-2.f * lC + (lW + lE)) + std::abs(-2.f * lN + (lNW + lNE)) + std::abs(-2.f * lS + (lSW + lSE))) /
      12.f;
  const float horz =
      (2.f * std::abs(-2.f * lC + (lN + lS)) + std::abs(-2.f * lW + (lNW + lSW)) + std::abs(-2.f * lE + (lNE + lSE))) /
      12.f;
  const bool horizontal = horz >= vert;
  // HC: the neighbour across the edge with the higher contrast to C (first guess north, or west).
  int px = horizontal ? 0 : -1, py = horizontal ? 1 : 0;
  const float l1 = horizontal ? lN : lW, l2 = horizontal ? lS : lE;
  float lHC = l1;
  if (!(std::abs(lC - l1) >= std::abs(lC - l2))) lHC = l2, px = -px, py = -py;

  // Walk along the edge in both directions, on C's row and HC's, until a sample is nearer the other side's luma.
  // "Positive" is +x along a horizontal edge and up the picture (y - 1) along a vertical one.
  const int ex = horizontal ? 1 : 0, ey = horizontal ? 0 : -1;
  float lHCN = 0, lCN = 0, lHCP = 0, lCP = 0;
  bool doneN = false, doneP = false;
  int n = 1, p = 1;  // steps from C to the current samples
  for (int i = 0; i < kSearchSteps; ++i) {
    if (!doneN) lHCN = s.l(x + px - n * ex, y + py - n * ey), lCN = s.l(x - n * ex, y - n * ey);
    if (!doneP) lHCP = s.l(x + px + p * ex, y + py + p * ey), lCP = s.l(x + p * ex, y + p * ey);
    doneN = doneN || std::abs(lHCN - lHC) > std::abs(lHCN - lC) || std::abs(lCN - lC) > std::abs(lCN - lHC);
    doneP = doneP || std::abs(lHCP - lHC) > std::abs(lHCP - lC) || std::abs(lCP - lC) > std::abs(lCP - lHC);
    if (doneN && doneP) break;
    if (!doneN) ++n;
    if (!doneP) ++p;
  }
  const bool near_n = n < p;
  const float dst = static_cast<float>(std::min(n, p));
  const float lnear = near_n ? lCN : lCP;
  const bool edge = std::abs(lnear - lHC) < std::abs(lnear - lC);

  // Resampled part of the way towards HC (linear filtering between C and HC), then the speck blend.
  const std::uint8_t* c = s.c(x, y);
  const std::uint8_t* hc = s.c(x + px, y + py);
  const float offset = edge ? dst * (-1.f / static_cast<float>(n + p)) + 0.5f : 0.f;
  bool changed = false;
  // Linear filtering as a texture unit does it on 8-bit texels (llvmpipe's: the weight in steps of 1/256, the
  // result rounded to 8 bits); in float the picture would differ from VTK's in ~25 times as many pixels, by one level.
  const int w = static_cast<int>(std::lround(offset * 256.f));
  for (int k = 0; k < 3; ++k) {
    const float e = to_unit(static_cast<std::uint8_t>((c[k] * 256 + (hc[k] - c[k]) * w + 128) >> 8));
    out[k] = to_byte(e + blend_sub * (mean[k] - e));
    changed = changed || out[k] != c[k];
  }
  return changed;
}

}  // namespace

void fxaa(Image& image, const PixelRect& r) {
  if (r.width < 1 || r.height < 1 || r.x < 0 || r.y < 0 || r.x + r.width > image.width ||
      r.y + r.height > image.height ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3)
    throw core::Error(fmt::format("fxaa: the rectangle {}x{} at ({}, {}) is not inside the {}x{} image", r.width,
                                  r.height, r.x, r.y, image.width, image.height));
  Source s;
  s.w = r.width, s.h = r.height;
  const std::size_t row = static_cast<std::size_t>(s.w) * 3;
  s.rgb.resize(Source::kRgbRows * row);
  s.luma.resize(Source::kLumaRows * static_cast<std::size_t>(s.w));
  auto pixels = [&](int y) {
    return image.rgb.data() +
           (static_cast<std::size_t>(r.y + y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(r.x)) *
               3;
  };
  // Rows are read (copied, their lumas computed) before any pixel of them is written: row y is written once the
  // rows up to y + 1 are copied and the lumas up to y + kSearchSteps + 2 computed, and it is not read again.
  int next_rgb = 0, next_luma = 0;
  std::uint8_t out[3];
  for (int y = 0; y < s.h; ++y) {
    for (; next_rgb <= std::min(y + 1, s.h - 1); ++next_rgb)
      std::memcpy(s.rgb.data() + static_cast<std::size_t>(Source::ring(next_rgb, Source::kRgbRows)) * row,
                  pixels(next_rgb), row);
    for (; next_luma <= std::min(y + kSearchSteps + 2, s.h - 1); ++next_luma) {
      const std::uint8_t* p = pixels(next_luma);
      float* l = s.luma.data() +
                 static_cast<std::size_t>(Source::ring(next_luma, Source::kLumaRows)) * static_cast<std::size_t>(s.w);
      for (int x = 0; x < s.w; ++x, p += 3)
        l[x] = to_unit(p[0]) * 0.299f + to_unit(p[1]) * 0.587f + to_unit(p[2]) * 0.114f;
    }
    for (int x = 0; x < s.w; ++x)
      if (smooth_pixel(s, x, y, out)) std::memcpy(pixels(y) + 3 * static_cast<std::size_t>(x), out, 3);
  }
}

}  // namespace vmsim::render
