#include "evar/acquisition/v4l2_frame_source.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>

#include "evar/acquisition/sequence_tracker.hpp"
#include "evar/acquisition/stream_state_reporter.hpp"
#include "v4l2_buffer_conversion.hpp"
#include "v4l2_io.hpp"
#include "wake_event.hpp"

namespace evar::acquisition {

namespace {

using Clock = std::chrono::steady_clock;

// A failed V4L2 call, with its errno so the caller can tell "gone" (ENODEV) from "refused".
struct V4l2Error : std::runtime_error {
  int error;
  V4l2Error(const std::string& what, int e) : std::runtime_error(what), error(e) {}
};

int retry_ioctl(V4l2Io& io, int fd, unsigned long request, void* arg) {
  int r;
  do r = io.ioctl(fd, request, arg);
  while (r == -1 && errno == EINTR);
  return r;
}

std::string errno_text(int e) { return std::string(strerrorname_np(e) ? strerrorname_np(e) : "E?") + " (" + std::strerror(e) + ")"; }

std::string device_gone_reason(int e) {
  return e == ENODEV || e == ENXIO || e == EIO ? "the device went away: " + errno_text(e) : errno_text(e);
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// One open V4L2 device and what was set up on it. The destructor undoes all of it in
// reverse (stream off, unmap, close), whichever step the setup reached.
class OpenDevice {
 public:
  OpenDevice(V4l2Io& io, std::string path) : io_(io), path_(std::move(path)) {
    fd_ = io_.open(path_.c_str(), O_RDWR | O_NONBLOCK);
    if (fd_ < 0) {
      const int e = errno;
      throw V4l2Error("cannot open " + path_ + ": " + errno_text(e), e);
    }
  }
  OpenDevice(const OpenDevice&) = delete;
  OpenDevice& operator=(const OpenDevice&) = delete;
  ~OpenDevice() {
    if (streaming_) {
      int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      retry_ioctl(io_, fd_, VIDIOC_STREAMOFF, &type);
    }
    for (const auto& m : maps_) io_.munmap(m.start, m.length);
    io_.close(fd_);
  }

  int fd() const { return fd_; }
  const std::string& path() const { return path_; }

  /// An ioctl that must succeed; throws naming the call and the device.
  void call(unsigned long request, void* arg, const char* name) {
    if (retry_ioctl(io_, fd_, request, arg) == -1) {
      const int e = errno;
      throw V4l2Error(path_ + ": " + name + " failed: " + errno_text(e), e);
    }
  }
  /// An ioctl that may fail; returns errno (0 on success).
  int try_call(unsigned long request, void* arg) { return retry_ioctl(io_, fd_, request, arg) == -1 ? errno : 0; }

  void map_buffers(int wanted) {
    v4l2_requestbuffers req{};
    req.count = static_cast<std::uint32_t>(wanted);
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    call(VIDIOC_REQBUFS, &req, "VIDIOC_REQBUFS");
    if (req.count < 2)
      throw V4l2Error(path_ + ": the driver granted " + std::to_string(req.count) + " buffers, streaming needs 2",
                      ENOMEM);
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      call(VIDIOC_QUERYBUF, &buf, "VIDIOC_QUERYBUF");
      void* p = io_.mmap(buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, static_cast<off_t>(buf.m.offset));
      if (p == MAP_FAILED) {
        const int e = errno;
        throw V4l2Error(path_ + ": mmap of buffer " + std::to_string(i) + " failed: " + errno_text(e), e);
      }
      maps_.push_back({p, buf.length});
    }
    for (std::uint32_t i = 0; i < req.count; ++i) queue(i);
  }

  void queue(std::uint32_t index) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = index;
    call(VIDIOC_QBUF, &buf, "VIDIOC_QBUF");
  }

  void stream_on() {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    call(VIDIOC_STREAMON, &type, "VIDIOC_STREAMON");
    streaming_ = true;
  }

  std::size_t buffer_count() const { return maps_.size(); }
  std::span<const std::uint8_t> buffer(std::uint32_t index, std::size_t bytes_used) const {
    const auto& m = maps_[index];
    return {static_cast<const std::uint8_t*>(m.start), std::min(bytes_used, m.length)};
  }

 private:
  struct Mapping {
    void* start;
    std::size_t length;
  };
  V4l2Io& io_;
  std::string path_;
  int fd_ = -1;
  std::vector<Mapping> maps_;
  bool streaming_ = false;
};

// The capture card and what it can do (VIDIOC_QUERYCAP, VIDIOC_ENUM_FMT).
struct Capabilities {
  std::string driver, card, bus_info;
  bool can_capture = false;
  std::vector<std::uint32_t> formats;
};

std::string text_field(const std::uint8_t* s, std::size_t n) {
  return std::string(reinterpret_cast<const char*>(s), strnlen(reinterpret_cast<const char*>(s), n));
}

Capabilities query(OpenDevice& d) {
  v4l2_capability cap{};
  d.call(VIDIOC_QUERYCAP, &cap, "VIDIOC_QUERYCAP");
  Capabilities c;
  c.driver = text_field(cap.driver, sizeof cap.driver);
  c.card = text_field(cap.card, sizeof cap.card);
  c.bus_info = text_field(cap.bus_info, sizeof cap.bus_info);
  // A node's own capabilities are in device_caps where the driver fills it.
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  c.can_capture = (caps & V4L2_CAP_VIDEO_CAPTURE) && (caps & V4L2_CAP_STREAMING);
  for (std::uint32_t i = 0; i < 256; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (d.try_call(VIDIOC_ENUM_FMT, &desc) != 0) break;  // EINVAL ends the list
    c.formats.push_back(desc.pixelformat);
  }
  return c;
}

}  // namespace

struct V4l2FrameSource::Impl {
  V4l2Options options;
  V4l2Io& io;
  FrameCallback on_frame;
  std::thread thread;
  std::atomic<bool> stop{false};
  WakeEvent wake{"V4L2 source"};  // stop() wakes the capture thread's poll

  mutable std::mutex mutex;  // guards what other threads read
  StreamStateReporter reporter;
  V4l2Statistics stats;
  SequenceStats earlier;  // frames of openings before the current one
  SequenceTracker tracker{32, 1024};  // v4l2_buffer.sequence is 32 bits
  std::optional<bool> use_buffer_times;  // per connection: buffer times (true) or arrival
  std::string refused;  // the last buffer refused since the last frame delivered (capture thread only)

  Impl(V4l2Options o, V4l2Io& i) : options(std::move(o)), io(i) {}

  void set_state(StreamState s, const std::string& why) { reporter.set(s, why); }

  bool wait_for_stop(std::chrono::milliseconds d) {
    return wake.wait(d) || stop;
  }

  // Why no frame came though buffers did ("" when none was refused since the last frame).
  std::string refused_text() const { return refused.empty() ? std::string() : "; buffers refused: " + refused; }

  void note_error(const std::string& e) {
    std::lock_guard lock(mutex);
    stats.last_error = e;
  }

  // Opens and negotiates; returns the device streaming and a line saying what was agreed.
  std::unique_ptr<OpenDevice> open_stream(std::string& agreed) {
    auto d = std::make_unique<OpenDevice>(io, options.device);
    const Capabilities caps = query(*d);
    if (!caps.can_capture)
      throw V4l2Error(options.device + " (" + caps.card + ") is not a video capture device with streaming I/O", ENOTTY);
    const std::vector<std::uint32_t>& wanted = options.formats.empty() ? readable_v4l2_formats() : options.formats;
    std::uint32_t fourcc = 0;
    for (auto w : wanted)
      if (std::find(caps.formats.begin(), caps.formats.end(), w) != caps.formats.end()) {
        fourcc = w;
        break;
      }
    if (fourcc == 0)
      throw V4l2Error(options.device + " (" + caps.card + ") offers " + fourcc_list(caps.formats) + "; asked for " +
                          fourcc_list(wanted),
                      EINVAL);

    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    d->call(VIDIOC_G_FMT, &fmt, "VIDIOC_G_FMT");
    fmt.fmt.pix.pixelformat = fourcc;
    if (options.width) fmt.fmt.pix.width = static_cast<std::uint32_t>(*options.width);
    if (options.height) fmt.fmt.pix.height = static_cast<std::uint32_t>(*options.height);
    fmt.fmt.pix.field = V4L2_FIELD_NONE;  // whole frames; interlaced ones (both fields in one buffer) are taken too
    fmt.fmt.pix.bytesperline = 0;  // let the driver choose its padding
    d->call(VIDIOC_S_FMT, &fmt, "VIDIOC_S_FMT");
    // The driver answers with what it will really do; that, not the request, is used.
    const auto& pix = fmt.fmt.pix;
    if (!is_readable_v4l2_format(pix.pixelformat))
      throw V4l2Error(options.device + ": asked for " + fourcc_to_string(fourcc) + ", the driver set " +
                          fourcc_to_string(pix.pixelformat) + ", which evarnode does not read",
                      EINVAL);
    // A buffer must hold a whole frame, its lines in order: progressive, or both fields
    // interleaved. Fields one per buffer or one after the other would be read as garbage.
    if (pix.field != V4L2_FIELD_NONE && pix.field != V4L2_FIELD_INTERLACED && pix.field != V4L2_FIELD_INTERLACED_TB &&
        pix.field != V4L2_FIELD_INTERLACED_BT && pix.field != V4L2_FIELD_ANY)
      throw V4l2Error(options.device + ": the driver delivers field order " + std::to_string(pix.field) +
                          " (fields in separate buffers or one after the other); evarnode reads progressive or "
                          "interleaved frames only",
                      EINVAL);
    if (pix.width == 0 || pix.height == 0 || pix.width > 16384 || pix.height > 16384 ||
        std::uint64_t{pix.width} * pix.height > std::uint64_t{8192} * 8192)
      throw V4l2Error(options.device + ": the driver set an implausible size " + size_text(static_cast<int>(pix.width), static_cast<int>(pix.height)), EINVAL);
    V4l2Layout layout{pix.pixelformat, static_cast<int>(pix.width), static_cast<int>(pix.height),
                      static_cast<int>(pix.bytesperline), pix.sizeimage};
    agreed = fourcc_to_string(layout.fourcc) + " " + size_text(layout.width, layout.height);
    if (pix.pixelformat != fourcc) agreed += " (asked for " + fourcc_to_string(fourcc) + ")";
    if ((options.width && *options.width != layout.width) || (options.height && *options.height != layout.height))
      agreed += " (asked for " + size_text(options.width.value_or(layout.width), options.height.value_or(layout.height)) + ")";

    std::optional<double> rate;
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    const bool has_parm = d->try_call(VIDIOC_G_PARM, &parm) == 0;
    if (options.frame_rate_hz && has_parm && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
      parm.parm.capture.timeperframe.numerator = 1000;
      parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(*options.frame_rate_hz * 1000.0));
      d->call(VIDIOC_S_PARM, &parm, "VIDIOC_S_PARM");
    } else if (options.frame_rate_hz) {
      agreed += " (the device does not take a frame rate)";
    }
    const auto& tpf = parm.parm.capture.timeperframe;
    if (has_parm && tpf.numerator > 0 && tpf.denominator > 0) {
      rate = static_cast<double>(tpf.denominator) / tpf.numerator;
      char buf[32];
      std::snprintf(buf, sizeof buf, " at %.3g Hz", *rate);
      agreed += buf;
    }

    d->map_buffers(options.buffers);
    d->stream_on();
    std::lock_guard lock(mutex);
    stats.driver = caps.driver;
    stats.card = caps.card;
    stats.bus_info = caps.bus_info;
    stats.layout = layout;
    stats.frame_rate_hz = rate;
    ++stats.connections;
    earlier += tracker.stats();
    tracker.reset();
    use_buffer_times.reset();
    return d;
  }

  // Takes the filled buffers off the queue, at most one round of the pool so stop() and
  // the watchdog are never starved by a camera faster than the frame handling; returns why
  // the device is lost, or empty.
  std::string drain(OpenDevice& d, Clock::time_point& last_frame) {
    for (std::size_t taken = 0; taken < d.buffer_count() && !stop; ++taken) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      if (const int e = d.try_call(VIDIOC_DQBUF, &buf); e != 0) {
        if (e == EAGAIN) return {};
        // EIO: videobuf2 has put the queue in its error state (it stays there until the
        // stream is turned off), so the device is reopened like a lost one.
        return "VIDIOC_DQBUF failed: " + device_gone_reason(e);
      }
      const Clock::time_point arrival = Clock::now();
      if (buf.index >= d.buffer_count()) return "the driver returned buffer " + std::to_string(buf.index) + " of " + std::to_string(d.buffer_count());
      handle(d, buf, arrival, last_frame);
      if (const int e = d.try_call(VIDIOC_QBUF, &buf); e != 0) return "VIDIOC_QBUF failed: " + device_gone_reason(e);
    }
    return {};
  }

  void handle(OpenDevice& d, const v4l2_buffer& buf, Clock::time_point arrival, Clock::time_point& last_frame) {
    V4l2Layout layout;
    {
      std::lock_guard lock(mutex);
      layout = stats.layout;
    }
    Frame f;
    std::optional<std::string> bad;
    if (buf.flags & V4L2_BUF_FLAG_ERROR)
      bad = "the driver flagged buffer " + std::to_string(buf.index) + " (sequence " + std::to_string(buf.sequence) + ") as corrupt";
    else
      bad = convert_v4l2_buffer(layout, d.buffer(buf.index, buf.bytesused), f);
    if (bad) {
      refused = *bad;
      std::lock_guard lock(mutex);
      ++stats.bad_buffers;
      stats.last_error = d.path() + ": " + *bad;
      return;
    }
    refused.clear();
    f.sequence = buf.sequence;
    f.host_arrival = arrival;
    const std::int64_t t_ns = std::int64_t{buf.timestamp.tv_sec} * 1'000'000'000 + std::int64_t{buf.timestamp.tv_usec} * 1000;
    f.device_time_ns = t_ns;
    // Monotonic buffer times are on the host's steady clock (CLOCK_MONOTONIC) already. Which
    // clock a connection's frames carry is decided once, on its first frame (a time after
    // arrival or long before is not believed), so frames never switch between two clocks.
    const Clock::time_point t{std::chrono::nanoseconds(t_ns)};
    if (!use_buffer_times) {
      const bool monotonic = (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
      use_buffer_times = monotonic && t <= arrival && arrival - t < std::chrono::seconds(2);
    }
    f.device_time_on_host = *use_buffer_times ? t : arrival;
    {
      std::lock_guard lock(mutex);
      tracker.observe(buf.sequence);
      stats.monotonic_timestamps = *use_buffer_times;
    }
    last_frame = arrival;
    set_state(StreamState::Streaming, options.device + " streaming " + fourcc_to_string(layout.fourcc) + " " +
                                          size_text(layout.width, layout.height));
    if (on_frame) on_frame(f);
  }

  void run() {
    bool in_outage = false;
    bool retrying = false;  // the last attempt to open failed: its reason stands until one succeeds
    int restarts_without_frames = 0;
    while (!stop) {
      // Said before the first attempt, not before every retry: the listener would hear the
      // two reasons in turn, twice a reconnect interval, for as long as the device is away.
      if (!retrying) set_state(StreamState::Connecting, "opening " + options.device);
      std::unique_ptr<OpenDevice> device;
      std::string agreed;
      try {
        device = open_stream(agreed);
        retrying = false;
      } catch (const V4l2Error& e) {
        device.reset();
        retrying = true;
        note_error(e.what());
        set_state(StreamState::Connecting, std::string(e.what()) + "; retrying every " +
                                               std::to_string(options.reconnect_interval.count()) + " ms");
        if (wait_for_stop(options.reconnect_interval)) break;
        continue;
      }
      in_outage = false;
      refused.clear();
      set_state(StreamState::Connecting, options.device + " open, " + agreed + ", waiting for the first frame");
      const Clock::time_point opened = Clock::now();
      Clock::time_point last_frame = opened;
      std::string lost;
      bool restart = false;
      // A grabber with no video signal delivers nothing; reopening it every few seconds
      // would only renegotiate the bus. Restarts back off while no frame comes.
      const auto restart_after = std::min<std::chrono::milliseconds>(
          options.restart_after * (1 << std::min(restarts_without_frames, 4)), std::chrono::seconds(60));
      while (!stop && lost.empty() && !restart) {
        pollfd fds[2] = {{device->fd(), POLLIN, 0}, {wake.fd(), POLLIN, 0}};
        const int n = io.poll(fds, 2, 100);
        if (n < 0 && errno != EINTR) lost = "poll failed: " + errno_text(errno);
        if (n > 0 && (fds[0].revents & (POLLERR | POLLHUP | POLLNVAL)))
          lost = std::string("poll reported ") + ((fds[0].revents & POLLHUP) ? "POLLHUP" : (fds[0].revents & POLLNVAL) ? "POLLNVAL" : "POLLERR");
        else if (n > 0 && (fds[0].revents & POLLIN))
          lost = drain(*device, last_frame);
        if (!lost.empty() || stop) break;
        const auto silent = Clock::now() - last_frame;
        if (last_frame != opened) restarts_without_frames = 0;
        if (silent > restart_after) {
          restart = true;
        } else if (silent > options.stall_after && last_frame == opened) {
          set_state(StreamState::Connecting, options.device + " open, " + agreed + ", no frame yet" +
                                                 (refused.empty() ? " (is there a video signal?)" : refused_text()));
        } else if (silent > options.stall_after && reporter.state() != StreamState::Stalled) {
          // Buffers that keep coming but are refused are said with the reason, as the
          // screen's only clue to a grabber whose format changed under it.
          set_state(StreamState::Stalled, options.device + ": no frame for " + std::to_string(options.stall_after.count()) +
                                              " ms" + refused_text());
        }
      }
      device.reset();  // stream off, unmap, close: a clean slate for the reopen
      if (stop) break;
      if (restart) {
        {
          std::lock_guard lock(mutex);
          ++stats.restarts;
        }
        const bool had_frames = last_frame != opened;
        if (!had_frames) ++restarts_without_frames;
        set_state(had_frames ? StreamState::Stalled : StreamState::Connecting,
                  options.device + ": no frame for " +
                      std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(restart_after).count()) +
                      " ms; reopening the device");
        continue;
      }
      if (!in_outage) {
        std::lock_guard lock(mutex);
        ++stats.outages;
        stats.last_error = options.device + ": " + lost;
      }
      in_outage = true;
      set_state(StreamState::Disconnected, options.device + " lost: " + lost + "; reopening");
      if (wait_for_stop(options.reconnect_interval)) break;
    }
    set_state(StreamState::Stopped, "V4L2 source " + options.device + " stopped");
  }

};

V4l2FrameSource::V4l2FrameSource(V4l2Options options) : V4l2FrameSource(std::move(options), system_v4l2_io()) {}

V4l2FrameSource::V4l2FrameSource(V4l2Options options, V4l2Io& io) {
  if (options.buffers < 2) throw std::invalid_argument("V4L2: need at least 2 buffers");
  if ((options.width && *options.width <= 0) || (options.height && *options.height <= 0))
    throw std::invalid_argument("V4L2: width and height must be positive");
  if (options.frame_rate_hz && !(*options.frame_rate_hz > 0.0 && *options.frame_rate_hz < 10000.0))
    throw std::invalid_argument("V4L2: frame rate must be positive (Hz)");
  for (auto f : options.formats)
    if (!is_readable_v4l2_format(f))
      throw std::invalid_argument("V4L2: format " + fourcc_to_string(f) + " is not one evarnode reads (GREY, Y16, YUYV, MJPG)");
  if (options.restart_after <= options.stall_after)
    throw std::invalid_argument("V4L2: restart_after must be longer than stall_after");
  impl_ = std::make_unique<Impl>(std::move(options), io);
}

V4l2FrameSource::~V4l2FrameSource() {
  stop();
}

void V4l2FrameSource::start(FrameCallback on_frame, StateCallback on_state) {
  if (impl_->thread.joinable()) throw std::logic_error("V4L2 source already started");
  impl_->wake.clear();
  impl_->on_frame = std::move(on_frame);
  impl_->reporter.listen(std::move(on_state));
  impl_->stop = false;
  impl_->thread = std::thread([this] { impl_->run(); });
}

void V4l2FrameSource::stop() {
  if (!impl_->thread.joinable()) return;
  impl_->stop = true;
  impl_->wake.signal();
  impl_->thread.join();  // the thread reported Stopped as its last word
}

StreamState V4l2FrameSource::state() const { return impl_->reporter.state(); }

SequenceStats V4l2FrameSource::statistics() const {
  std::lock_guard lock(impl_->mutex);
  SequenceStats s = impl_->earlier;
  return s += impl_->tracker.stats();
}

V4l2Statistics V4l2FrameSource::v4l2_statistics() const {
  std::lock_guard lock(impl_->mutex);
  V4l2Statistics s = impl_->stats;
  s.frames = impl_->earlier;
  s.frames += impl_->tracker.stats();
  return s;
}

std::string V4l2FrameSource::description() const {
  const auto& o = impl_->options;
  return "V4L2 device " + o.device + ", " + fourcc_list(o.formats.empty() ? readable_v4l2_formats() : o.formats);
}

std::vector<V4l2DeviceInfo> list_v4l2_devices() { return list_v4l2_devices(system_v4l2_io(), "/dev"); }

std::vector<V4l2DeviceInfo> list_v4l2_devices(V4l2Io& io, const std::filesystem::path& dev_dir) {
  std::vector<std::pair<long, std::filesystem::path>> nodes;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dev_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() <= 5 || name.compare(0, 5, "video") != 0) continue;
    if (!std::all_of(name.begin() + 5, name.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    if (name.size() > 12) continue;  // not a plausible minor number
    nodes.emplace_back(std::stol(name.substr(5)), entry.path());
  }
  std::sort(nodes.begin(), nodes.end());
  std::vector<V4l2DeviceInfo> out;
  for (const auto& [number, path] : nodes) {
    V4l2DeviceInfo info;
    info.path = path.string();
    try {
      OpenDevice d(io, info.path);
      const Capabilities c = query(d);
      info.driver = c.driver;
      info.card = c.card;
      info.bus_info = c.bus_info;
      info.can_capture = c.can_capture;
      info.formats = c.formats;
    } catch (const V4l2Error& e) {
      info.error = e.what();
    }
    out.push_back(std::move(info));
  }
  return out;
}

}  // namespace evar::acquisition
