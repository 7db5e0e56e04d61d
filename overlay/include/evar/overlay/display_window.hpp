#pragma once
// The bedside monitor: a window (fullscreen if asked) showing the composited frames alone
// (no toolbar), opened at the frames' size, with
// keys: m cycles the roadmap mode, f toggles fullscreen, s asks for a snapshot, q or Esc
// asks to stop. All calls from one thread (the GUI toolkit's rule).
#include <memory>
#include <string>

#include "evar/overlay/mesh_preview.hpp"

namespace evar::overlay {

enum class WindowKey { None, CycleMode, Snapshot, Quit };

class DisplayWindow {
 public:
  /// std::runtime_error when there is no display (DISPLAY and WAYLAND_DISPLAY unset) or
  /// the window cannot be made.
  DisplayWindow(std::string title, bool fullscreen);
  ~DisplayWindow();
  DisplayWindow(const DisplayWindow&) = delete;
  DisplayWindow& operator=(const DisplayWindow&) = delete;

  /// Shows the frame and handles pending window events; returns the key pressed, if any
  /// that means something to the caller (f is handled here).
  WindowKey show(const Image& frame);

 private:
  std::string title_;
  bool fullscreen_;
  int shown_width_ = 0, shown_height_ = 0;  // the size the window was given
};

}  // namespace evar::overlay
