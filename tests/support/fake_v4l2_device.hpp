#pragma once
// A scripted V4L2 capture device behind the V4l2Io seam, for tests on machines without
// /dev/video* (no kernel video driver can be loaded here). It follows the V4L2 rules the
// grabber depends on: S_FMT adjusts rather than refuses, REQBUFS may grant fewer buffers,
// STREAMON restarts the sequence counter, a frame with no queued buffer is lost inside the
// driver (the counter still advances), an unplugged device answers ENODEV to every call and
// POLLERR|POLLHUP to poll while its mappings stay valid until unmapped. The test thread
// scripts the sensor (produce, skip, unplug, plug); the grabber's thread makes the calls.
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <deque>
#include <list>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "v4l2_io.hpp"

namespace evar::test {

class FakeV4l2Device final : public acquisition::V4l2Io {
 public:
  struct Config {
    std::string path = "/dev/video-fake";
    std::string driver = "evarfake", card = "Scripted grabber", bus_info = "platform:evarfake";
    std::vector<std::uint32_t> formats{V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_Y16, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
    int width = 64, height = 48;           ///< the format before anyone sets one
    int max_width = 1024, max_height = 1024;
    int width_step = 1;                    ///< widths are rounded down to a multiple of this
    int row_padding = 0;                   ///< bytes added to every line
    bool capture = true;                   ///< a capture node (false: e.g. a metadata node)
    std::uint32_t max_buffers = 8;
    bool takes_frame_rate = true;
    std::uint32_t timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    std::uint32_t field = V4L2_FIELD_NONE;  ///< the field order the driver insists on
  };

  explicit FakeV4l2Device(Config c) : config_(std::move(c)) {
    ready_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    format_.pixelformat = config_.formats.empty() ? V4L2_PIX_FMT_GREY : config_.formats.front();
    apply_size(config_.width, config_.height);
  }
  ~FakeV4l2Device() override {
    for (auto& [fd, dead] : fds_) ::close(fd);
    ::close(ready_fd_);
  }

  // ---- the sensor, scripted by the test -------------------------------------------------

  /// One frame from the sensor: lands in the oldest queued buffer, or is lost inside the
  /// driver when none is queued. Returns true when it landed.
  bool produce(const std::vector<std::uint8_t>& payload, std::uint32_t extra_flags = 0) {
    std::lock_guard lock(mutex_);
    if (!streaming_ || unplugged_) return false;
    const std::uint32_t sequence = next_sequence_++;
    if (queued_.empty()) return false;  // lost inside the driver: the sequence skips it
    const std::uint32_t index = queued_.front();
    queued_.pop_front();
    auto& memory = (*buffers_)[index];
    const std::size_t n = std::min(payload.size(), memory.size());
    std::memcpy(memory.data(), payload.data(), n);
    Filled f{index, static_cast<std::uint32_t>(n), extra_flags, sequence, {}};
    ::clock_gettime(CLOCK_MONOTONIC, &f.time);
    done_.push_back(f);
    update_ready();
    return true;
  }
  /// Frames lost inside the driver: the sequence counter jumps by n.
  void skip(std::uint32_t n) {
    std::lock_guard lock(mutex_);
    next_sequence_ += n;
  }
  /// The device node disappears (USB cable pulled).
  void unplug() {
    std::lock_guard lock(mutex_);
    unplugged_ = true;
    for (auto& [fd, dead] : fds_) dead = true;
    streaming_ = false;
    queued_.clear();
    done_.clear();
    owner_ = -1;
    retire_buffers();
    update_ready();
    changed_.notify_all();
  }
  void plug() {
    std::lock_guard lock(mutex_);
    unplugged_ = false;
    update_ready();
  }
  /// The next VIDIOC_DQBUF fails with this errno (e.g. ENODEV).
  void fail_next_dqbuf(int error) {
    std::lock_guard lock(mutex_);
    dqbuf_error_ = error;
  }
  /// The queue enters videobuf2's error state: DQBUF answers EIO and poll POLLERR until
  /// the stream is turned off.
  void queue_error() {
    std::lock_guard lock(mutex_);
    queue_error_ = true;
    update_ready();
  }

  // ---- what the grabber did -----------------------------------------------------------

  bool wait_streaming(std::chrono::milliseconds timeout, int stream_ons_at_least = 1) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return streaming_ && stream_ons_ >= stream_ons_at_least; });
  }
  bool wait_closed(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return fds_.empty() && mapped_ == 0; });
  }
  v4l2_pix_format format() const {
    std::lock_guard lock(mutex_);
    return format_;
  }
  int opens() const {
    std::lock_guard lock(mutex_);
    return opens_;
  }
  int open_fds() const {
    std::lock_guard lock(mutex_);
    return static_cast<int>(fds_.size());
  }
  double frame_rate_set() const {
    std::lock_guard lock(mutex_);
    return static_cast<double>(timeperframe_.denominator) / timeperframe_.numerator;
  }

  // ---- V4l2Io ---------------------------------------------------------------------------

  int open(const char* path, int /*flags*/) override {
    std::lock_guard lock(mutex_);
    if (path != config_.path || unplugged_) return fail(ENOENT);
    const int fd = ::eventfd(0, EFD_CLOEXEC);  // a real descriptor number, never read
    fds_[fd] = false;
    ++opens_;
    changed_.notify_all();
    return fd;
  }

  int close(int fd) override {
    std::lock_guard lock(mutex_);
    auto it = fds_.find(fd);
    if (it == fds_.end()) return fail(EBADF);
    if (!it->second && owner_ == fd) {  // closing the streaming descriptor frees the queue
      streaming_ = false;
      queued_.clear();
      done_.clear();
      owner_ = -1;
      queue_error_ = false;
      retire_buffers();
      update_ready();
    }
    fds_.erase(it);
    ::close(fd);
    changed_.notify_all();
    return 0;
  }

  void* mmap(std::size_t length, int /*prot*/, int /*flags*/, int fd, off_t offset) override {
    std::lock_guard lock(mutex_);
    if (!live(fd)) {
      errno = fds_.count(fd) ? ENODEV : EBADF;
      return MAP_FAILED;
    }
    const auto index = static_cast<std::size_t>(offset / kPage);
    if (!buffers_ || offset % kPage != 0 || index >= buffers_->size() || length > (*buffers_)[index].size()) {
      errno = EINVAL;
      return MAP_FAILED;
    }
    ++mapped_;
    return (*buffers_)[index].data();
  }

  int munmap(void* /*address*/, std::size_t /*length*/) override {
    std::lock_guard lock(mutex_);
    if (mapped_ == 0) return fail(EINVAL);
    --mapped_;
    changed_.notify_all();
    return 0;
  }

  int poll(pollfd* fds, nfds_t count, int timeout_ms) override {
    // Device descriptors wait on the ready eventfd; the caller's own descriptors as given.
    std::vector<pollfd> real(fds, fds + count);
    {
      std::lock_guard lock(mutex_);
      for (auto& p : real)
        if (fds_.count(p.fd)) p = {ready_fd_, POLLIN, 0};
    }
    const int n = ::poll(real.data(), count, timeout_ms);
    if (n < 0) return n;
    std::lock_guard lock(mutex_);
    int ready = 0;
    for (nfds_t i = 0; i < count; ++i) {
      fds[i].revents = 0;
      auto it = fds_.find(fds[i].fd);
      if (it == fds_.end()) {
        fds[i].revents = real[i].revents;
      } else if (it->second || unplugged_) {
        fds[i].revents = POLLERR | POLLHUP;
      } else if (!streaming_ || owner_ != fds[i].fd || queue_error_) {
        fds[i].revents = POLLERR;  // as V4L2 does when the descriptor is not streaming or the queue failed
      } else if (!done_.empty()) {
        fds[i].revents = POLLIN;
      }
      ready += fds[i].revents != 0;
    }
    return ready;
  }

  int ioctl(int fd, unsigned long request, void* arg) override {
    std::lock_guard lock(mutex_);
    auto it = fds_.find(fd);
    if (it == fds_.end()) return fail(EBADF);
    if (it->second || unplugged_) return fail(ENODEV);
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* cap = static_cast<v4l2_capability*>(arg);
        *cap = {};
        copy_text(cap->driver, sizeof cap->driver, config_.driver);
        copy_text(cap->card, sizeof cap->card, config_.card);
        copy_text(cap->bus_info, sizeof cap->bus_info, config_.bus_info);
        cap->device_caps = config_.capture ? (V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING) : V4L2_CAP_META_CAPTURE;
        cap->capabilities = cap->device_caps | V4L2_CAP_DEVICE_CAPS;
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* d = static_cast<v4l2_fmtdesc*>(arg);
        if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || d->index >= config_.formats.size()) return fail(EINVAL);
        d->pixelformat = config_.formats[d->index];
        d->flags = d->pixelformat == V4L2_PIX_FMT_MJPEG ? V4L2_FMT_FLAG_COMPRESSED : 0;
        return 0;
      }
      case VIDIOC_G_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        f->fmt.pix = format_;
        return 0;
      }
      case VIDIOC_S_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        if (buffers_) return fail(EBUSY);
        const auto& want = config_.formats;
        format_.pixelformat = std::find(want.begin(), want.end(), f->fmt.pix.pixelformat) != want.end()
                                  ? f->fmt.pix.pixelformat
                                  : want.front();  // V4L2: adjust, never refuse
        apply_size(static_cast<int>(f->fmt.pix.width), static_cast<int>(f->fmt.pix.height));
        f->fmt.pix = format_;
        return 0;
      }
      case VIDIOC_G_PARM:
      case VIDIOC_S_PARM: {
        auto* p = static_cast<v4l2_streamparm*>(arg);
        if (p->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || !config_.takes_frame_rate) return fail(ENOTTY);
        if (request == VIDIOC_S_PARM && p->parm.capture.timeperframe.numerator > 0 &&
            p->parm.capture.timeperframe.denominator > 0)
          timeperframe_ = p->parm.capture.timeperframe;
        p->parm.capture = {};
        p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
        p->parm.capture.timeperframe = timeperframe_;
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* r = static_cast<v4l2_requestbuffers*>(arg);
        if (r->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || r->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
        if (streaming_ || mapped_ > 0) return fail(EBUSY);
        retire_buffers();
        r->count = std::min(r->count, config_.max_buffers);
        if (r->count > 0) {
          buffers_ = &storage_.emplace_back(r->count, std::vector<std::uint8_t>(format_.sizeimage));
          owner_ = fd;
        }
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (!buffers_ || b->index >= buffers_->size()) return fail(EINVAL);
        b->length = static_cast<std::uint32_t>((*buffers_)[b->index].size());
        b->m.offset = b->index * kPage;
        return 0;
      }
      case VIDIOC_QBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (!buffers_ || b->index >= buffers_->size() || owner_ != fd) return fail(EINVAL);
        if (std::find(queued_.begin(), queued_.end(), b->index) != queued_.end()) return fail(EINVAL);
        queued_.push_back(b->index);
        return 0;
      }
      case VIDIOC_DQBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (dqbuf_error_) return fail(std::exchange(dqbuf_error_, 0));
        if (queue_error_) return fail(EIO);
        if (!streaming_ || owner_ != fd) return fail(EINVAL);
        if (done_.empty()) return fail(EAGAIN);
        const Filled f = done_.front();
        done_.pop_front();
        update_ready();
        b->index = f.index;
        b->bytesused = f.bytes;
        b->flags = f.flags | config_.timestamp_flags | V4L2_BUF_FLAG_DONE;
        b->sequence = f.sequence;
        b->timestamp.tv_sec = f.time.tv_sec;
        b->timestamp.tv_usec = f.time.tv_nsec / 1000;
        b->field = V4L2_FIELD_NONE;
        b->length = static_cast<std::uint32_t>((*buffers_)[f.index].size());
        return 0;
      }
      case VIDIOC_STREAMON:
        if (!buffers_ || owner_ != fd) return fail(EINVAL);
        streaming_ = true;
        next_sequence_ = 0;  // drivers restart the count at STREAMON
        ++stream_ons_;
        changed_.notify_all();
        return 0;
      case VIDIOC_STREAMOFF:
        streaming_ = false;
        queue_error_ = false;
        queued_.clear();
        done_.clear();
        update_ready();
        return 0;
      default:
        return fail(ENOTTY);
    }
  }

 private:
  static constexpr std::uint32_t kPage = 4096;
  struct Filled {
    std::uint32_t index, bytes, flags, sequence;
    timespec time;
  };

  static int fail(int e) {
    errno = e;
    return -1;
  }
  static void copy_text(std::uint8_t* dst, std::size_t n, const std::string& s) {
    std::memcpy(dst, s.data(), std::min(n - 1, s.size()));
  }
  bool live(int fd) const {
    auto it = fds_.find(fd);
    return it != fds_.end() && !it->second && !unplugged_;
  }
  void apply_size(int w, int h) {
    w = std::clamp(w, 16, config_.max_width);
    h = std::clamp(h, 16, config_.max_height);
    w -= w % std::max(1, config_.width_step);
    format_.width = static_cast<std::uint32_t>(w);
    format_.height = static_cast<std::uint32_t>(h);
    format_.field = config_.field;
    const int bpp = format_.pixelformat == V4L2_PIX_FMT_GREY ? 1 : 2;
    if (format_.pixelformat == V4L2_PIX_FMT_MJPEG) {
      format_.bytesperline = 0;
      format_.sizeimage = static_cast<std::uint32_t>(w * h + 4096);
    } else {
      format_.bytesperline = static_cast<std::uint32_t>(w * bpp + config_.row_padding);
      format_.sizeimage = format_.bytesperline * format_.height;
    }
  }
  // Buffers are kept until the fake dies: a grabber may still hold mappings to them, as
  // the kernel keeps a vanished device's buffers until they are unmapped.
  void retire_buffers() { buffers_ = nullptr; }
  void update_ready() {
    const bool want = unplugged_ || queue_error_ || !done_.empty();
    if (want == signalled_) return;
    std::uint64_t v = 1;
    [[maybe_unused]] const auto n = want ? ::write(ready_fd_, &v, sizeof v) : ::read(ready_fd_, &v, sizeof v);
    signalled_ = want;
  }

  Config config_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  int ready_fd_ = -1;
  bool signalled_ = false;
  std::map<int, bool> fds_;  // open descriptors → dead (opened before an unplug)
  int owner_ = -1;           // the descriptor that allocated the buffers
  v4l2_pix_format format_{};
  v4l2_fract timeperframe_{1, 30};
  std::list<std::vector<std::vector<std::uint8_t>>> storage_;  // every buffer set ever made
  std::vector<std::vector<std::uint8_t>>* buffers_ = nullptr;  // the current set
  std::deque<std::uint32_t> queued_;
  std::deque<Filled> done_;
  bool streaming_ = false, unplugged_ = false, queue_error_ = false;
  std::uint32_t next_sequence_ = 0;
  int dqbuf_error_ = 0;
  int opens_ = 0, stream_ons_ = 0, mapped_ = 0;
};

}  // namespace evar::test
