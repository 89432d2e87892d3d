#pragma once
// FXAA (fast approximate anti-aliasing, NVIDIA's FXAA whitepaper; VTK's variant of it) run on the CPU over a
// rectangle of a finished picture. VTK's vtkOpenGLFXAAFilter does the same per pixel in a fragment shader, which on
// Mesa's llvmpipe (no GPU) costs ~0.1-0.2 s of CPU a 1600 x 1200 picture; here most pixels stop after five luma
// lookups, so a picture costs a few tens of ms (bench/README.md "Pictures' CPU, round 4").
#include "render/image.hpp"

namespace vmsim::render {

// The rectangle of an image that is smoothed (pixels, x from the left, y from the top); outside it nothing changes,
// and pixels beyond its edges read as the nearest pixel inside it (as VTK's filter samples its viewport's texture).
struct PixelRect {
  int x = 0, y = 0, width = 0, height = 0;
};

// VTK's FXAA with vtkOpenGLFXAAFilter's defaults (relative contrast threshold 1/8, hard 1/16, sub-pixel blend limit
// 3/4, sub-pixel contrast threshold 1/4, 12 endpoint search steps, VTK's "high quality" endpoint search), applied in
// place. A pixel whose luma differs from its four neighbours by less than the thresholds is left as it is; an edge
// pixel is resampled part of the way towards the pixel across the edge and blended with its 3 x 3 mean where it is
// a lone speck. Throws core::Error when the rectangle is not inside the image.
void fxaa(Image& image, const PixelRect& rect);

}  // namespace vmsim::render
