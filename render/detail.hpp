#pragma once
// Shared by render/*.cpp only (not a public header): the few VTK-facing helpers every picture uses. VTK types are
// forward-declared so that this header stays light; the VTK headers themselves are included in the .cpp files.
#include "render/image.hpp"
#include "render/window.hpp"

#include <string>
#include <vector>

class vtkRenderWindow;
class vtkRenderer;
class vtkTextProperty;

namespace vmsim::render::detail {

// Throws core::Error unless 16 <= width, height <= 16384 (names `what`).
void check_size(int width, int height, const char* what);

// The window's VTK render window, emptied of any previous picture's renderers and set to width x height.
vtkRenderWindow* begin_picture(Window& window, int width, int height);

// Sets the window's samples per pixel and, for FxaaVtk, the renderer's FXAA pass (it smooths that renderer's
// viewport). Fxaa is the caller's to apply to the picture's pixels (render/fxaa.hpp) after finish_picture.
void set_antialiasing(vtkRenderWindow* window, vtkRenderer* renderer, Antialiasing aa);

// Renders the window's renderers and reads the colour buffer; then removes the renderers (releasing their GL
// objects while the context is current). Throws core::Error with VTK's message when VTK reported an error.
Image finish_picture(Window& window);

// Text in DejaVu Sans (STACK.md P8: Debian's VTK substitute for Arial draws '[' and ']' as parentheses).
void set_font(vtkTextProperty* text, int size_px, double r, double g, double b, bool bold = false);

// Collects VTK's error and warning messages while alive (instead of printing them), so that a failed picture
// becomes a core::Error naming what VTK said. Nested captures share one collection.
class VtkMessages {
 public:
  VtkMessages();
  ~VtkMessages();
  VtkMessages(const VtkMessages&) = delete;
  VtkMessages& operator=(const VtkMessages&) = delete;
  // Throws core::Error("<what>: VTK: <first error>") when an error was reported since construction.
  void check(const std::string& what) const;
  std::vector<std::string> warnings() const;

 private:
  std::size_t first_error_, first_warning_;
};

}  // namespace vmsim::render::detail
