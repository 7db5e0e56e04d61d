// The bedside window on a real X server: Xvfb, started by the test on a display of its own.
// What the monitor shows is read back from the server's screen (not from our buffers), and
// the keys are pressed through the XTEST extension, as a keyboard would.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

#include "evar/overlay/display_window.hpp"

// Named before Xlib's macros (None, Bool, Status) can take these words over.
namespace {
constexpr evar::overlay::WindowKey kNoKey = evar::overlay::WindowKey::None;
}

#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/extensions/XTest.h>
#include <X11/keysym.h>

// Under the sanitizers (scripts/test.sh with EVAR_SANITIZE=1) the GUI toolkit's own
// libraries report what is not ours: libdbus keeps a 1 KiB buffer until exit (LSan), and
// libxkbcommon-x11 calls strndup on a name that is not NUL-terminated, which is legal but
// trips ASan's strict_string_checks (tests/CMakeLists.txt turns that check off for this
// program only).
extern "C" const char* __lsan_default_suppressions() { return "leak:libdbus-1.so\n"; }

namespace {

using evar::overlay::Bgr;
using evar::overlay::DisplayWindow;
using evar::overlay::Image;
using evar::overlay::WindowKey;
using Clock = std::chrono::steady_clock;

constexpr const char* kXvfb = "/usr/bin/Xvfb";

// An X server of our own for the whole test program: Xvfb picks a free display and tells
// us its number (-displayfd). The GUI toolkit keeps its connection until the process ends,
// so the server lives as long as we do and goes with us (PR_SET_PDEATHSIG).
const std::string& virtual_display() {
  static const std::string name = [] {
    int fds[2];
    if (::pipe(fds) != 0) throw std::runtime_error("pipe");
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      ::close(fds[0]);
      const std::string fd = std::to_string(fds[1]);
      ::execl(kXvfb, kXvfb, "-displayfd", fd.c_str(), "-screen", "0", "1280x1024x24", "-nolisten", "tcp",
              static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    std::string number;
    char c = 0;
    while (::read(fds[0], &c, 1) == 1 && c != '\n') number += c;
    ::close(fds[0]);
    if (number.empty()) throw std::runtime_error("Xvfb did not start");
    return ":" + number;
  }();
  return name;
}

// The test's own connection to the server, to find the window, read the screen and type.
class XClient {
 public:
  explicit XClient(const std::string& display) : d_(XOpenDisplay(display.c_str())) {
    if (!d_) throw std::runtime_error("cannot open display " + display);
  }
  ~XClient() { XCloseDisplay(d_); }
  Display* get() const { return d_; }

  /// The window titled `title`, searched depth first from the root.
  std::optional<Window> find(const std::string& title) const { return find(DefaultRootWindow(d_), title); }

  /// Its rectangle in screen coordinates.
  void rectangle(Window w, int& x, int& y, unsigned& width, unsigned& height) const {
    XWindowAttributes a{};
    XGetWindowAttributes(d_, w, &a);
    Window child = 0;
    XTranslateCoordinates(d_, w, DefaultRootWindow(d_), 0, 0, &x, &y, &child);
    width = static_cast<unsigned>(a.width);
    height = static_cast<unsigned>(a.height);
  }

  /// Share of the pixels in the screen rectangle that are near `colour` (within 40 per channel).
  double share_of(int x, int y, unsigned width, unsigned height, Bgr colour) const {
    XImage* image = XGetImage(d_, DefaultRootWindow(d_), x, y, width, height, AllPlanes, ZPixmap);
    if (!image) return 0.0;
    std::size_t near = 0;
    for (unsigned j = 0; j < height; ++j)
      for (unsigned i = 0; i < width; ++i) {
        const unsigned long p = XGetPixel(image, static_cast<int>(i), static_cast<int>(j));
        const int r = static_cast<int>((p >> 16) & 0xff), g = static_cast<int>((p >> 8) & 0xff), b = static_cast<int>(p & 0xff);
        near += std::abs(r - colour.r) < 40 && std::abs(g - colour.g) < 40 && std::abs(b - colour.b) < 40;
      }
    XDestroyImage(image);
    return static_cast<double>(near) / static_cast<double>(std::size_t{width} * height);
  }

  void press(Window w, KeySym key) const {
    XSetInputFocus(d_, w, RevertToParent, CurrentTime);
    const KeyCode code = XKeysymToKeycode(d_, key);
    XTestFakeKeyEvent(d_, code, True, CurrentTime);
    XTestFakeKeyEvent(d_, code, False, CurrentTime);
    XFlush(d_);
  }

 private:
  std::optional<Window> find(Window w, const std::string& title) const {
    char* name = nullptr;
    if (XFetchName(d_, w, &name) && name) {
      const bool match = title == name;
      XFree(name);
      XWindowAttributes a{};
      if (match && XGetWindowAttributes(d_, w, &a) && a.map_state == IsViewable) return w;
    }
    Window root = 0, parent = 0, *children = nullptr;
    unsigned n = 0;
    if (!XQueryTree(d_, w, &root, &parent, &children, &n)) return std::nullopt;
    std::optional<Window> found;
    for (unsigned i = 0; i < n && !found; ++i) found = find(children[i], title);
    if (children) XFree(children);
    return found;
  }

  Display* d_;
};

// Left half one colour, right half another.
Image halves(int width, int height, Bgr left, Bgr right) {
  Image image = Image::filled(width, height, left);
  for (int y = 0; y < height; ++y)
    for (int x = width / 2; x < width; ++x) {
      std::uint8_t* p = &image.bgr[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3];
      p[0] = right.b;
      p[1] = right.g;
      p[2] = right.r;
    }
  return image;
}

class DisplayWindowOnXvfb : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kXvfb)) GTEST_SKIP() << "Xvfb is not installed (scripts/install-deps.sh installs it)";
    ::setenv("DISPLAY", virtual_display().c_str(), 1);
    ::unsetenv("WAYLAND_DISPLAY");
    ::setenv("QT_QPA_PLATFORM", "xcb", 1);
    client_.emplace(virtual_display());
  }
  std::optional<XClient> client_;
};

// Shows `frame` until the window is on screen and its left and right halves show the two
// colours (at least `share` of each, all but 2 px at the edges); false after 10 s.
bool shows(DisplayWindow& window, const Image& frame, const XClient& x, Bgr left, Bgr right, double share,
           double* left_share = nullptr, double* right_share = nullptr, unsigned* width = nullptr,
           unsigned* height = nullptr) {
  const auto until = Clock::now() + std::chrono::seconds(10);
  double l = 0, r = 0;
  while (Clock::now() < until) {
    window.show(frame);
    if (const auto w = x.find("evarnode")) {
      int wx = 0, wy = 0;
      unsigned ww = 0, wh = 0;
      x.rectangle(*w, wx, wy, ww, wh);
      if (width) *width = ww;
      if (height) *height = wh;
      if (ww >= 8 && wh >= 8) {
        // Each half of the window whole but for 2 px at its edges.
        const unsigned half = ww / 2 - 4;
        l = x.share_of(wx + 2, wy + 2, half, wh - 4, left);
        r = x.share_of(wx + static_cast<int>(ww / 2) + 2, wy + 2, half, wh - 4, right);
        if (l >= share && r >= share) break;
      }
    }
  }
  if (left_share) *left_share = l;
  if (right_share) *right_share = r;
  return l >= share && r >= share;
}

TEST_F(DisplayWindowOnXvfb, ShowsEachNewFrameOnTheScreen) {
  DisplayWindow window("evarnode", false);
  const Bgr red{0, 0, 255}, blue{255, 0, 0};
  double l = 0, r = 0;
  unsigned width = 0, height = 0;
  // The picture alone fills the window, one frame pixel per screen pixel: no toolbar or
  // status bar around it on a bedside monitor (with them, 9 % of the window was not the
  // picture). 98 %: antialiasing at the seam.
  EXPECT_TRUE(shows(window, halves(640, 480, red, blue), *client_, red, blue, 0.98, &l, &r, &width, &height))
      << "left " << l << " red, right " << r << " blue";
  EXPECT_EQ(width, 640u);
  EXPECT_EQ(height, 480u);
  // A new frame replaces it: the screen follows the video, it does not keep the first.
  EXPECT_TRUE(shows(window, halves(640, 480, blue, red), *client_, blue, red, 0.98, &l, &r))
      << "left " << l << " blue, right " << r << " red";
}

TEST_F(DisplayWindowOnXvfb, AnswersTheKeysTheClinicianPresses) {
  DisplayWindow window("evarnode", false);
  const Image frame = halves(320, 240, {40, 40, 40}, {200, 200, 200});
  ASSERT_TRUE(shows(window, frame, *client_, {40, 40, 40}, {200, 200, 200}, 0.9));
  const Window w = *client_->find("evarnode");
  // Each key is answered within 5 s of frames (the window reads keys while it shows them).
  const auto answer = [&](KeySym key) {
    client_->press(w, key);
    const auto until = Clock::now() + std::chrono::seconds(5);
    while (Clock::now() < until) {
      const WindowKey k = window.show(frame);
      if (k != kNoKey) return k;
    }
    return kNoKey;
  };
  EXPECT_EQ(answer(XK_m), WindowKey::CycleMode);
  EXPECT_EQ(answer(XK_s), WindowKey::Snapshot);
  EXPECT_EQ(answer(XK_q), WindowKey::Quit);
  EXPECT_EQ(answer(XK_Escape), WindowKey::Quit);
  // f toggles fullscreen inside the window and is not the caller's business.
  EXPECT_EQ(answer(XK_f), kNoKey);
}

TEST(DisplayWindow, WithoutADisplayItSaysSoAndWhatToUseInstead) {
  const char* had = std::getenv("DISPLAY");
  const std::string saved = had ? had : "";
  ::unsetenv("DISPLAY");
  ::unsetenv("WAYLAND_DISPLAY");
  try {
    DisplayWindow window("evarnode", false);
    ADD_FAILURE() << "a window without a display";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("DISPLAY is not set"), std::string::npos) << what;
    EXPECT_NE(what.find("video"), std::string::npos) << what;
  }
  if (had) ::setenv("DISPLAY", saved.c_str(), 1);
}

}  // namespace
