#include "evar/overlay/display_window.hpp"

#include <cstdlib>
#include <stdexcept>

#include <opencv2/highgui.hpp>
#include "image_mat.hpp"

namespace evar::overlay {

DisplayWindow::DisplayWindow(std::string title, bool fullscreen) : title_(std::move(title)), fullscreen_(fullscreen) {
  if (std::getenv("DISPLAY") == nullptr && std::getenv("WAYLAND_DISPLAY") == nullptr)
    throw std::runtime_error("no display to open a window on (DISPLAY is not set); write a video or use OpenIGTLink");
  try {
    // GUI_NORMAL: the picture alone, without the toolkit's toolbar and pixel-value status
    // bar, which a bedside monitor has no use for and which would shrink the picture.
    cv::namedWindow(title_, cv::WINDOW_NORMAL | cv::WINDOW_KEEPRATIO | cv::WINDOW_GUI_NORMAL);
    cv::setWindowProperty(title_, cv::WND_PROP_FULLSCREEN, fullscreen_ ? cv::WINDOW_FULLSCREEN : cv::WINDOW_NORMAL);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot open a window: " + e.msg);
  }
}

DisplayWindow::~DisplayWindow() {
  try {
    cv::destroyWindow(title_);
  } catch (const cv::Exception&) {
    // the toolkit may already be gone at exit
  }
}

WindowKey DisplayWindow::show(const Image& frame) {
  // A resizable window opens at the toolkit's default size: give it the frame's, one
  // detector pixel per screen pixel, and again when the frames change size.
  if (!fullscreen_ && (frame.width != shown_width_ || frame.height != shown_height_)) {
    cv::resizeWindow(title_, frame.width, frame.height);
    shown_width_ = frame.width;
    shown_height_ = frame.height;
  }
  cv::imshow(title_, detail::wrap(frame));
  const int key = cv::waitKey(1);
  switch (key & 0xff) {
    case 'm': return WindowKey::CycleMode;
    case 's': return WindowKey::Snapshot;
    case 'q':
    case 27: return WindowKey::Quit;
    case 'f':
      fullscreen_ = !fullscreen_;
      shown_width_ = shown_height_ = 0;  // back from fullscreen: the frame's size again
      cv::setWindowProperty(title_, cv::WND_PROP_FULLSCREEN, fullscreen_ ? cv::WINDOW_FULLSCREEN : cv::WINDOW_NORMAL);
      return WindowKey::None;
    default: return WindowKey::None;
  }
}

}  // namespace evar::overlay
