#pragma once
// The headless render window: an OpenGL context on Mesa's EGL "surfaceless" platform (no X server, no DISPLAY,
// no Xvfb; STACK.md section 3, recipe A) under a VTK render window. Debian's VTK 9.1 is built for X11 only: its own
// windows abort() without a display, so every picture vmsim draws goes through this class.
//
// One Window holds one context, made once when the Window is constructed and kept for all the pictures drawn with
// it (VTK keeps its compiled shaders per window, so reusing a Window is much faster than making one per picture).
// A Window is used from one thread at a time.
#include <memory>
#include <string>

namespace vmsim::render {

// How edges are smoothed. On Mesa's llvmpipe (no GPU) 4x multisampling costs ~0.2 s of CPU per 1600 x 1200 picture
// even for an empty one, plus ~0.6 s for a part of 0.6 M triangles; FXAA as VTK's shader ~0.1-0.2 s, on the CPU
// a few tens of ms (bench/README.md "Pictures' CPU", "round 4").
enum class Antialiasing {
  None,     // every pixel one sample: exact colours, stair-stepped edges
  Fxaa,     // NVIDIA's FXAA over the finished scene (render/fxaa.hpp, on the CPU): smooth silhouettes, a slight
            // softening of one-pixel detail
  Msaa4,    // 4 samples per pixel
  FxaaVtk,  // the same FXAA run by VTK as a shader (vtkOpenGLFXAAFilter): Fxaa's reference, ~0.1 s more a picture
};

class Window {
 public:
  // Makes the EGL display, context and VTK window. Throws core::Error, naming the EGL call and its error code
  // (e.g. EGL_NOT_INITIALIZED 0x3001) and what to install, when no context can be made; it never aborts.
  Window();
  ~Window();
  Window(const Window&) = delete;
  Window& operator=(const Window&) = delete;

  // "Mesa/X.org llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6": for reports and bench notes.
  const std::string& gl_description() const;

  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace vmsim::render
