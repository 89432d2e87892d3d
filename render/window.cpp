// The headless window (STACK.md section 3, recipe A): Mesa's EGL surfaceless platform gives an OpenGL 3.2+ core
// context with no X server; a vtkGenericOpenGLRenderWindow subclass renders into it. VTK 9.1 renders into its own
// framebuffer objects, so the context needs no window-system surface at all.
#include <vtk_glew.h>  // first: GLEW must see no other GL header before it

#include "render/detail.hpp"
#include "render/image.hpp"
#include "render/window.hpp"

#include "core/memory.hpp"
#include "core/error.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkPointData.h>
#include <vtkRenderer.h>
#include <vtkRendererCollection.h>
#include <vtkSmartPointer.h>
#include <vtkTextProperty.h>
#include <vtkUnsignedCharArray.h>

#include <fmt/format.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>

namespace vmsim::render {

namespace {

// ---- VTK's messages -------------------------------------------------------------------------------------------

// Replaces VTK's output window once per process. While a VtkMessages capture is alive, errors and warnings are
// collected (and become a core::Error with VTK's text); otherwise they go to stderr as VTK would print them.
class CapturingOutputWindow : public vtkOutputWindow {
 public:
  static CapturingOutputWindow* New();
  vtkTypeMacro(CapturingOutputWindow, vtkOutputWindow);

  void DisplayErrorText(const char* text) override { record(text, true); }
  void DisplayWarningText(const char* text) override { record(text, false); }
  void DisplayGenericWarningText(const char* text) override { record(text, false); }

  std::mutex mutex;
  int captures = 0;
  std::vector<std::string> errors, warnings;

 protected:
  CapturingOutputWindow() = default;

 private:
  void record(const char* text, bool error) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (captures > 0) {
        (error ? errors : warnings).emplace_back(text ? text : "");
        return;
      }
    }
    std::fprintf(stderr, "%s", text ? text : "");
  }
};
vtkStandardNewMacro(CapturingOutputWindow);

CapturingOutputWindow& output_window() {
  static CapturingOutputWindow* w = [] {
    // VTK also sends every error to its logger, which prints it to stderr on its own, captured or not: this
    // window becomes the only place VTK's messages go.
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
    CapturingOutputWindow* ow = CapturingOutputWindow::New();
    vtkOutputWindow::SetInstance(ow);  // VTK keeps a reference
    ow->Delete();
    return ow;
  }();
  return *w;
}

// VTK's error text is "ERROR: In file, line N\nvtkClass (0x...): message\n\n": keep the message.
std::string vtk_message(const std::string& text) {
  std::string s = text;
  if (const auto nl = s.find('\n'); s.rfind("ERROR: In ", 0) == 0 || s.rfind("Warning: In ", 0) == 0)
    if (nl != std::string::npos) s = s.substr(nl + 1);
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

// ---- EGL ------------------------------------------------------------------------------------------------------

const char* egl_error_name(EGLint e) {
  switch (e) {
    case EGL_SUCCESS:
      return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CURRENT_SURFACE:
      return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_SURFACE:
      return "EGL_BAD_SURFACE";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    case EGL_BAD_NATIVE_PIXMAP:
      return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW:
      return "EGL_BAD_NATIVE_WINDOW";
    case EGL_CONTEXT_LOST:
      return "EGL_CONTEXT_LOST";
    default:
      return "unknown EGL error";
  }
}

constexpr const char* kEglHelp =
    " (vmsim renders through Mesa's EGL surfaceless platform, no X server needed: it needs the Debian packages "
    "libegl1, libegl-mesa0 and libgl1-mesa-dri; run without images with --no-render)";

[[noreturn]] void egl_fail(const std::string& call) {
  const EGLint e = eglGetError();
  throw core::Error(fmt::format("cannot create the headless OpenGL context: {} failed with {} (0x{:04X}){}", call,
                                egl_error_name(e), static_cast<unsigned>(e), kEglHelp));
}

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

// One EGL display for the process: Mesa hands out the same display for the same platform anyway, and
// eglTerminate would invalidate the contexts of every other Window alive.
EGLDisplay surfaceless_display() {
  static std::mutex m;
  static EGLDisplay dpy = EGL_NO_DISPLAY;
  std::lock_guard<std::mutex> lock(m);
  if (dpy != EGL_NO_DISPLAY) return dpy;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_MESA_platform_surfaceless"))
    throw core::Error(std::string("cannot create the headless OpenGL context: the EGL library offers no "
                                  "EGL_MESA_platform_surfaceless platform (client extensions: ") +
                      (client && *client ? client : "none") + ")" + kEglHelp);
  auto get_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!get_display)
    throw core::Error(std::string("cannot create the headless OpenGL context: no eglGetPlatformDisplayEXT") + kEglHelp);
  EGLDisplay d = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (d == EGL_NO_DISPLAY) egl_fail("eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA)");
  EGLint major = 0, minor = 0;
  if (!eglInitialize(d, &major, &minor)) egl_fail("eglInitialize");
  dpy = d;
  return dpy;
}

// ---- the VTK window on that context ------------------------------------------------------------------------------

class HeadlessRenderWindow : public vtkGenericOpenGLRenderWindow {
 public:
  static HeadlessRenderWindow* New();
  vtkTypeMacro(HeadlessRenderWindow, vtkGenericOpenGLRenderWindow);

  void attach(EGLDisplay dpy, EGLSurface surf, EGLContext ctx) {
    Dpy = dpy, Surf = surf, Ctx = ctx;
    SetIsDirect(true);
    SetSupportsOpenGL(true);
    SetIsCurrent(true);
    SetReadyForRendering(true);
    SetMapped(1);
    SetOwnContext(0);
    SetFrameBlitModeToNoBlit();  // nothing to show: VTK's own framebuffers hold the picture
    SetOffScreenRendering(1);
  }
  void detach() {
    if (Ctx == EGL_NO_CONTEXT) return;
    MakeCurrent();
    Finalize();  // VTK's GL objects are freed while their context is still current
    Dpy = EGL_NO_DISPLAY, Surf = EGL_NO_SURFACE, Ctx = EGL_NO_CONTEXT;
    SetReadyForRendering(false);
  }
  void MakeCurrent() override {
    if (Ctx != EGL_NO_CONTEXT && eglGetCurrentContext() != Ctx) eglMakeCurrent(Dpy, Surf, Surf, Ctx);
  }
  bool IsCurrent() override { return Ctx != EGL_NO_CONTEXT && eglGetCurrentContext() == Ctx; }

 protected:
  HeadlessRenderWindow() = default;
  ~HeadlessRenderWindow() override { detach(); }

  // Debian's GLEW is built for GLX: glewInit() loads every entry point through GLVND and then returns
  // GLEW_ERROR_NO_GLX_DISPLAY, which stock VTK treats as fatal (it logs and leaves the window half set up).
  void OpenGLInitContext() override {
    if (!this->Initialized) {
      glewExperimental = GL_TRUE;
      const GLenum r = glewInit();
      if (r != GLEW_OK && r != GLEW_ERROR_NO_GLX_DISPLAY) {
        vtkErrorMacro("glewInit failed with GLEW error " << r);
        return;
      }
      this->Initialized = true;
    }
    this->Superclass::OpenGLInitContext();
  }

 private:
  EGLDisplay Dpy = EGL_NO_DISPLAY;
  EGLSurface Surf = EGL_NO_SURFACE;
  EGLContext Ctx = EGL_NO_CONTEXT;
};
vtkStandardNewMacro(HeadlessRenderWindow);

constexpr const char* kFontFile = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
constexpr const char* kBoldFontFile = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf";

}  // namespace

// ---- Window ------------------------------------------------------------------------------------------------------

struct Window::Impl {
  EGLDisplay dpy = EGL_NO_DISPLAY;
  EGLSurface surf = EGL_NO_SURFACE;
  EGLContext ctx = EGL_NO_CONTEXT;
  vtkSmartPointer<HeadlessRenderWindow> win;
  std::string description;

  ~Impl() {
    if (win) win->detach();
    win = nullptr;
    if (ctx != EGL_NO_CONTEXT) {
      if (eglGetCurrentContext() == ctx) eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(dpy, ctx);
    }
    if (surf != EGL_NO_SURFACE) eglDestroySurface(dpy, surf);
  }
};

Window::Window() : impl_(std::make_unique<Impl>()) {
  output_window();
  Impl& m = *impl_;
  m.dpy = surfaceless_display();
  if (!eglBindAPI(EGL_OPENGL_API)) egl_fail("eglBindAPI(EGL_OPENGL_API)");
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE,
                                   EGL_PBUFFER_BIT,
                                   EGL_RED_SIZE,
                                   8,
                                   EGL_GREEN_SIZE,
                                   8,
                                   EGL_BLUE_SIZE,
                                   8,
                                   EGL_ALPHA_SIZE,
                                   8,
                                   EGL_DEPTH_SIZE,
                                   24,
                                   EGL_RENDERABLE_TYPE,
                                   EGL_OPENGL_BIT,
                                   EGL_NONE};
  EGLConfig config = nullptr;
  EGLint n = 0;
  if (!eglChooseConfig(m.dpy, config_attribs, &config, 1, &n)) egl_fail("eglChooseConfig");
  if (n < 1)
    throw core::Error(std::string("cannot create the headless OpenGL context: eglChooseConfig found no RGBA8 + depth "
                                  "24 OpenGL configuration") +
                      kEglHelp);
  // VTK 9.1 draws into its own framebuffer objects; the context needs a surface only where
  // EGL_KHR_surfaceless_context is missing, and then a token one.
  if (!has_extension(eglQueryString(m.dpy, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context")) {
    const EGLint pbuffer_attribs[] = {EGL_WIDTH, 16, EGL_HEIGHT, 16, EGL_NONE};
    m.surf = eglCreatePbufferSurface(m.dpy, config, pbuffer_attribs);
    if (m.surf == EGL_NO_SURFACE) egl_fail("eglCreatePbufferSurface");
  }
  const EGLint context_attribs[] = {
      EGL_CONTEXT_MAJOR_VERSION,           3,       EGL_CONTEXT_MINOR_VERSION, 2, EGL_CONTEXT_OPENGL_PROFILE_MASK,
      EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  m.ctx = eglCreateContext(m.dpy, config, EGL_NO_CONTEXT, context_attribs);
  if (m.ctx == EGL_NO_CONTEXT) egl_fail("eglCreateContext(OpenGL 3.2 core)");
  if (!eglMakeCurrent(m.dpy, m.surf, m.surf, m.ctx)) egl_fail("eglMakeCurrent");

  detail::VtkMessages messages;
  m.win = vtkSmartPointer<HeadlessRenderWindow>::New();
  m.win->attach(m.dpy, m.surf, m.ctx);
  m.win->SetSize(64, 64);
  m.win->SetMultiSamples(0);
  m.win->Initialize();  // GLEW and VTK's GL state, now rather than in the middle of the first picture
  messages.check("cannot set up VTK on the headless OpenGL context");
  const auto gl_string = [](GLenum e) {
    const auto* s = reinterpret_cast<const char*>(glGetString(e));
    return std::string(s ? s : "?");
  };
  m.description = gl_string(GL_VENDOR) + " " + gl_string(GL_RENDERER) + ", OpenGL " + gl_string(GL_VERSION);
}

Window::~Window() = default;

const std::string& Window::gl_description() const { return impl_->description; }

// ---- detail ------------------------------------------------------------------------------------------------------

namespace detail {

void check_size(int width, int height, const char* what) {
  if (width < 16 || height < 16 || width > 16384 || height > 16384)
    throw core::Error(fmt::format("{}: image size {}x{} is outside 16..16384 pixels", what, width, height));
  // What a picture holds while it is drawn and written (the off-screen colour and depth buffers, VTK's copy, the PNG
  // writer's): about 17 B per pixel, from the 4.4 GB measured at 16384 x 16384 (issue 18); checked against the memory
  // available, before the window is sized.
  const double need = 17.0 * width * height;
  const core::AvailableMemory avail = core::available_memory();
  if (need > avail.bytes)
    throw core::Error(
        fmt::format("{}: a {}x{} picture needs about {} while {} is available ({}); choose a smaller "
                    "picture (--image-size of vmsim run, --size of vmsim render)",
                    what, width, height, core::format_bytes(need), core::format_bytes(avail.bytes), avail.source));
}

vtkRenderWindow* begin_picture(Window& window, int width, int height) {
  HeadlessRenderWindow* w = window.impl().win;
  w->MakeCurrent();
  vtkRendererCollection* rs = w->GetRenderers();
  while (rs->GetNumberOfItems() > 0) w->RemoveRenderer(vtkRenderer::SafeDownCast(rs->GetItemAsObject(0)));
  w->SetSize(width, height);
  return w;
}

void set_antialiasing(vtkRenderWindow* window, vtkRenderer* renderer, Antialiasing aa) {
  window->SetMultiSamples(aa == Antialiasing::Msaa4 ? 4 : 0);
  renderer->SetUseFXAA(aa == Antialiasing::FxaaVtk);  // Fxaa is applied to the read-back pixels (render/fxaa.hpp)
}

Image finish_picture(Window& window) {
  HeadlessRenderWindow* w = window.impl().win;
  VtkMessages messages;
  w->Render();
  const int* size = w->GetSize();
  Image img;
  img.width = size[0];
  img.height = size[1];
  vtkNew<vtkUnsignedCharArray> pixels;
  w->GetPixelData(0, 0, img.width - 1, img.height - 1, /*front=*/0, pixels, /*right=*/0);
  // GL rows run bottom-up.
  img.rgb.resize(static_cast<std::size_t>(img.width) * img.height * 3);
  if (pixels->GetNumberOfValues() == static_cast<vtkIdType>(img.rgb.size())) {
    const std::size_t row = static_cast<std::size_t>(img.width) * 3;
    for (int y = 0; y < img.height; ++y)
      std::memcpy(img.rgb.data() + static_cast<std::size_t>(y) * row,
                  pixels->GetPointer(static_cast<vtkIdType>((img.height - 1 - y) * row)), row);
  }
  vtkRendererCollection* rs = w->GetRenderers();
  while (rs->GetNumberOfItems() > 0) w->RemoveRenderer(vtkRenderer::SafeDownCast(rs->GetItemAsObject(0)));
  messages.check("rendering failed");
  if (pixels->GetNumberOfValues() != static_cast<vtkIdType>(img.rgb.size()))
    throw core::Error(fmt::format("rendering failed: read {} bytes of pixels, expected {}", pixels->GetNumberOfValues(),
                                  img.rgb.size()));
  return img;
}

void set_font(vtkTextProperty* t, int size_px, double r, double g, double b, bool bold) {
  static const bool have_dejavu = [] {
    const bool ok = std::filesystem::exists(kFontFile) && std::filesystem::exists(kBoldFontFile);
    if (!ok)
      std::fprintf(stderr,
                   "vmsim: warning: %s is missing (Debian package fonts-dejavu-core); text is drawn in VTK's "
                   "own font, which shows '[' and ']' as parentheses\n",
                   kFontFile);
    return ok;
  }();
  if (have_dejavu) {
    t->SetFontFamily(VTK_FONT_FILE);
    t->SetFontFile(bold ? kBoldFontFile : kFontFile);
  } else {
    t->SetFontFamilyToArial();
    t->SetBold(bold);
  }
  t->SetFontSize(size_px);
  t->SetColor(r, g, b);
  t->SetShadow(false);
  t->SetItalic(false);
}

VtkMessages::VtkMessages() {
  CapturingOutputWindow& ow = output_window();
  std::lock_guard<std::mutex> lock(ow.mutex);
  ++ow.captures;
  first_error_ = ow.errors.size();
  first_warning_ = ow.warnings.size();
}

VtkMessages::~VtkMessages() {
  CapturingOutputWindow& ow = output_window();
  std::lock_guard<std::mutex> lock(ow.mutex);
  if (--ow.captures == 0) {
    ow.errors.clear();
    ow.warnings.clear();
  }
}

void VtkMessages::check(const std::string& what) const {
  CapturingOutputWindow& ow = output_window();
  std::lock_guard<std::mutex> lock(ow.mutex);
  if (ow.errors.size() > first_error_) {
    std::string msg = what + ": VTK: " + vtk_message(ow.errors[first_error_]);
    if (ow.errors.size() > first_error_ + 1) msg += fmt::format(" (and {} more)", ow.errors.size() - first_error_ - 1);
    throw core::Error(msg);
  }
}

std::vector<std::string> VtkMessages::warnings() const {
  CapturingOutputWindow& ow = output_window();
  std::lock_guard<std::mutex> lock(ow.mutex);
  std::vector<std::string> w;
  for (std::size_t k = first_warning_; k < ow.warnings.size(); ++k) w.push_back(vtk_message(ow.warnings[k]));
  return w;
}

}  // namespace detail

}  // namespace vmsim::render
