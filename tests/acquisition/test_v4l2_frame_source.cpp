// The V4L2 grabber against a scripted device behind the V4l2Io seam (no /dev/video* and no
// loadable video driver exist on the machines these tests run on): format negotiation with
// read-back, streaming with pixels checked, drops from sequence gaps, bad buffers, the
// watchdog, and teardown and reopen when the device goes away. (Buffer conversion:
// test_v4l2_buffer_conversion.cpp.)
#include <gtest/gtest.h>

#include <mutex>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <atomic>
#include <future>
#include <thread>

#include "evar/acquisition/v4l2_frame_source.hpp"
#include "support/fake_v4l2_device.hpp"
#include "support/stream_log.hpp"
#include "support/v4l2_test_pattern.hpp"

namespace evar::acquisition {
namespace {

using namespace std::chrono_literals;
using test::FakeV4l2Device;
using test::mismatches;
using test::payload_for;

struct FrameLog : test::StreamLog {
  std::vector<Frame> frames;
  FrameSource::FrameCallback frame_callback() {
    return [this](const Frame& f) { record([&] { frames.push_back(f); }); };
  }
  FrameSource::StateCallback state_callback() {
    return [this](StreamState s, const std::string& r) { on_stream(s, r); };
  }
};

V4l2Options quick_options(const std::string& path) {
  V4l2Options o;
  o.device = path;
  o.stall_after = 150ms;
  o.restart_after = 20s;  // never within a test, except where the watchdog is the subject
  o.reconnect_interval = 50ms;
  return o;
}

// A scripted device with a started grabber on it (the log outlives the grabber).
struct Grabbing {
  FakeV4l2Device device;
  FrameLog log;
  V4l2FrameSource source;
  explicit Grabbing(const FakeV4l2Device::Config& c) : Grabbing(c, quick_options(c.path)) {}
  Grabbing(const FakeV4l2Device::Config& c, const V4l2Options& o) : device(c), source(o, device) {
    source.start(log.frame_callback(), log.state_callback());
  }
};

// ---- negotiation -------------------------------------------------------------------------

TEST(V4l2FrameSource, TakesTheDeepestOfferedGreyAndUsesTheSizeTheDriverGrants) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY};  // no Y16 on this grabber
  c.max_width = 640;
  c.max_height = 480;
  c.width_step = 16;
  V4l2Options o = quick_options(c.path);
  o.width = 1000;  // more than the grabber can
  o.height = 700;
  o.frame_rate_hz = 25.0;
  Grabbing g(c, o);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  EXPECT_EQ(device.format().pixelformat, V4L2_PIX_FMT_GREY);
  EXPECT_EQ(device.format().width, 640u);
  EXPECT_NEAR(device.frame_rate_set(), 25.0, 1e-9);
  device.produce(payload_for(device.format(), 1));
  ASSERT_TRUE(log.wait([&] { return !log.frames.empty(); }, 5s));
  source.stop();
  EXPECT_EQ(log.frames[0].width, 640);
  EXPECT_EQ(log.frames[0].height, 480);
  EXPECT_EQ(log.frames[0].format, PixelFormat::Mono8);
  EXPECT_EQ(mismatches(log.frames[0], 1), 0);
  const auto stats = source.v4l2_statistics();
  EXPECT_EQ(stats.layout.fourcc, V4L2_PIX_FMT_GREY);
  EXPECT_EQ(stats.card, "Scripted grabber");
  ASSERT_TRUE(stats.frame_rate_hz);
  EXPECT_NEAR(*stats.frame_rate_hz, 25.0, 1e-9);
  // What was granted instead of what was asked is told, not hidden.
  EXPECT_TRUE(log.said({"GREY 640x480", "asked for 1000x700"}));
}

TEST(V4l2FrameSource, ADeviceWithoutAReadableFormatIsReportedNamingWhatItOffers) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_RGB24, V4L2_PIX_FMT_NV12};
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(log.wait([&] { return log.said({"offers RGB3, NV12", "Y16 , GREY, YUYV, MJPG"}); }, 5s));
  EXPECT_EQ(source.state(), StreamState::Connecting);
  source.stop();
  EXPECT_TRUE(log.frames.empty());
  EXPECT_TRUE(device.wait_closed(1s)) << "a refused device is closed again";
}

TEST(V4l2FrameSource, ANodeThatIsNotACaptureDeviceIsRefused) {
  FakeV4l2Device::Config c;
  c.capture = false;  // e.g. the metadata node a UVC grabber also creates
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(log.wait([&] { return log.said({"not a video capture device"}); }, 5s));
  source.stop();
}

TEST(V4l2FrameSource, BadOptionsThrowBeforeAnythingStarts) {
  FakeV4l2Device device({});
  V4l2Options o;
  o.buffers = 1;
  EXPECT_THROW(V4l2FrameSource(o, device), std::invalid_argument);
  o = {};
  o.formats = {V4L2_PIX_FMT_RGB24};
  EXPECT_THROW(V4l2FrameSource(o, device), std::invalid_argument);
  o = {};
  o.frame_rate_hz = 0.0;
  EXPECT_THROW(V4l2FrameSource(o, device), std::invalid_argument);
}

// ---- streaming ---------------------------------------------------------------------------

TEST(V4l2FrameSource, StreamsEveryFrameInOrderWithPixelsAndMonotonicTimes) {
  FakeV4l2Device::Config c;
  c.row_padding = 24;  // a driver that pads its lines
  c.width = 200;
  c.height = 120;
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  ASSERT_EQ(device.format().pixelformat, V4L2_PIX_FMT_Y16) << "Y16 is preferred when offered";
  constexpr int n = 40;
  for (int i = 0; i < n; ++i) {
    // The sensor waits for the grabber like a real frame period would.
    ASSERT_TRUE(log.wait([&] { return static_cast<int>(log.frames.size()) >= i; }, 5s));
    ASSERT_TRUE(device.produce(payload_for(device.format(), i)));
  }
  ASSERT_TRUE(log.wait([&] { return log.frames.size() == n; }, 5s));
  source.stop();
  for (int i = 0; i < n; ++i) {
    const Frame& f = log.frames[static_cast<std::size_t>(i)];
    EXPECT_EQ(f.sequence, static_cast<std::uint64_t>(i));
    EXPECT_EQ(f.format, PixelFormat::Mono16);
    EXPECT_EQ(mismatches(f, i), 0) << "frame " << i;
    // The buffer time is the kernel's CLOCK_MONOTONIC: the host clock, before arrival.
    EXPECT_LE(f.device_time_on_host, f.host_arrival);
    EXPECT_LT(f.host_arrival - f.device_time_on_host, 1s);
    if (i > 0) {
      EXPECT_GE(f.device_time_ns, log.frames[static_cast<std::size_t>(i - 1)].device_time_ns);
    }
  }
  const auto stats = source.v4l2_statistics();
  EXPECT_EQ(stats.frames.received, static_cast<std::uint64_t>(n));
  EXPECT_EQ(stats.frames.dropped, 0u);
  EXPECT_EQ(stats.bad_buffers, 0u);
  EXPECT_TRUE(stats.monotonic_timestamps);
  EXPECT_TRUE(log.saw(StreamState::Streaming));
  EXPECT_EQ(log.streams.back().first, StreamState::Stopped);
  EXPECT_TRUE(device.wait_closed(1s)) << "stop() unmaps every buffer and closes the device";
}

// A driver may grant fewer buffers than asked (VIDIOC_REQBUFS lowers the count): the
// grabber streams with the two it gets; with one it cannot stream and says so.
TEST(V4l2FrameSource, ADriverGrantingTwoOfTheFourBuffersAskedIsStreamedWithThem) {
  FakeV4l2Device::Config c;
  c.max_buffers = 2;
  FakeV4l2Device device(c);
  FrameLog log;
  // The first frame is held in its callback until released: its buffer stays out of the
  // queue meanwhile, so the sensor finds exactly one other buffer to fill.
  std::mutex gate;
  std::unique_lock hold(gate);
  V4l2FrameSource source(quick_options(c.path), device);
  source.start(
      [&](const Frame& f) {
        if (f.sequence == 0) std::lock_guard wait_for_release(gate);
        log.record([&] { log.frames.push_back(f); });
      },
      log.state_callback());
  ASSERT_TRUE(device.wait_streaming(5s));
  ASSERT_TRUE(device.produce(payload_for(device.format(), 0)));
  EXPECT_TRUE(device.produce(payload_for(device.format(), 1))) << "the second buffer was not queued";
  EXPECT_FALSE(device.produce(payload_for(device.format(), 2))) << "a third buffer was queued: more than granted";
  hold.unlock();
  ASSERT_TRUE(log.wait([&] { return log.frames.size() == 2; }, 5s));
  // Released, both buffers cycle again: frames land one after another as they are taken.
  for (int i = 3; i < 20; ++i) {
    ASSERT_TRUE(log.wait([&] { return static_cast<int>(log.frames.size()) >= i - 1; }, 5s));
    ASSERT_TRUE(device.produce(payload_for(device.format(), i))) << "frame " << i;
  }
  ASSERT_TRUE(log.wait([&] { return log.frames.size() == 19; }, 5s));
  source.stop();
  EXPECT_EQ(source.v4l2_statistics().frames.dropped, 1u) << "frame 2, lost inside the driver";
  for (const Frame& f : log.frames) EXPECT_EQ(mismatches(f, static_cast<int>(f.sequence)), 0) << "frame " << f.sequence;
}

TEST(V4l2FrameSource, ADriverGrantingOneBufferIsReportedNotStreamed) {
  FakeV4l2Device::Config c;
  c.max_buffers = 1;
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(log.wait([&] { return log.said({"/dev/video-fake", "granted 1 buffers, streaming needs 2"}); }, 5s));
  source.stop();
  EXPECT_FALSE(log.saw(StreamState::Streaming));
  EXPECT_TRUE(log.frames.empty());
  EXPECT_TRUE(device.wait_closed(1s)) << "the refused device is closed again";
}

TEST(V4l2FrameSource, YuyvAndMjpegGrabbersDeliverGreyFrames) {
  for (std::uint32_t fourcc : {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG}) {
    FakeV4l2Device::Config c;
    c.formats = {fourcc};
    Grabbing g(c);
    auto& [device, log, source] = g;
    ASSERT_TRUE(device.wait_streaming(5s));
    const auto fmt = device.format();
    std::vector<std::uint8_t> payload;
    if (fourcc == V4L2_PIX_FMT_MJPEG) {
      cv::Mat img(static_cast<int>(fmt.height), static_cast<int>(fmt.width), CV_8UC1, cv::Scalar(77));
      cv::imencode(".jpg", img, payload);
    } else {
      payload = payload_for(fmt, 5);
    }
    ASSERT_TRUE(device.produce(payload));
    ASSERT_TRUE(log.wait([&] { return !log.frames.empty(); }, 5s)) << fourcc_to_string(fourcc);
    source.stop();
    const Frame& f = log.frames[0];
    EXPECT_EQ(f.format, PixelFormat::Mono8);
    if (fourcc == V4L2_PIX_FMT_MJPEG) {
      for (auto v : f.pixels) ASSERT_NEAR(v, 77, 1);  // a flat image survives JPEG
    } else {
      EXPECT_EQ(mismatches(f, 5), 0);
    }
  }
}

TEST(V4l2FrameSource, SequenceGapsAreDropsAndBadBuffersAreCountedNotDelivered) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  const auto fmt = device.format();
  auto next = [&](std::size_t expect_frames) {
    return log.wait([&] { return log.frames.size() >= expect_frames; }, 5s);
  };
  device.produce(payload_for(fmt, 0));  // sequence 0
  ASSERT_TRUE(next(1));
  device.skip(3);                        // 1, 2, 3 lost in the driver
  device.produce(payload_for(fmt, 4));  // 4
  ASSERT_TRUE(next(2));
  device.produce(payload_for(fmt, 5), V4L2_BUF_FLAG_ERROR);  // 5: corrupt
  device.produce(std::vector<std::uint8_t>(10, 1));          // 6: far too short
  device.produce(payload_for(fmt, 7));                        // 7
  ASSERT_TRUE(next(3));
  source.stop();
  ASSERT_EQ(log.frames.size(), 3u);
  EXPECT_EQ(log.frames[1].sequence, 4u);
  EXPECT_EQ(log.frames[2].sequence, 7u);
  EXPECT_EQ(mismatches(log.frames[2], 7), 0);
  const auto stats = source.v4l2_statistics();
  EXPECT_EQ(stats.bad_buffers, 2u);
  EXPECT_EQ(stats.frames.received, 3u);
  EXPECT_EQ(stats.frames.dropped, 5u) << "3 lost in the driver and 2 bad buffers never shown";
  EXPECT_NE(stats.last_error.find("holds 10 bytes"), std::string::npos) << stats.last_error;
}

TEST(V4l2FrameSource, BufferTimesNotOnTheMonotonicClockAreReplacedByArrival) {
  FakeV4l2Device::Config c;
  c.timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_COPY;
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  device.produce(payload_for(device.format(), 0));
  ASSERT_TRUE(log.wait([&] { return !log.frames.empty(); }, 5s));
  source.stop();
  EXPECT_EQ(log.frames[0].device_time_on_host, log.frames[0].host_arrival);
  EXPECT_FALSE(source.v4l2_statistics().monotonic_timestamps);
}

// ---- the device going away ---------------------------------------------------------------

TEST(V4l2FrameSource, AnUnpluggedGrabberIsReportedTornDownAndReopenedWhenItReturns) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(log.wait([&] { return static_cast<int>(log.frames.size()) >= i; }, 5s));
    device.produce(payload_for(device.format(), i));
  }
  ASSERT_TRUE(log.wait([&] { return log.frames.size() == 5; }, 5s));

  device.unplug();
  ASSERT_TRUE(log.wait([&] { return log.saw(StreamState::Disconnected); }, 5s));
  // Torn down completely: the vanished device's buffers unmapped and its descriptor closed.
  EXPECT_TRUE(device.wait_closed(5s));
  // While it is away the reason says so.
  ASSERT_TRUE(log.wait([&] { return log.said({"cannot open", "ENOENT"}); }, 5s));
  EXPECT_NE(source.state(), StreamState::Streaming);

  device.plug();
  ASSERT_TRUE(device.wait_streaming(5s, 2));
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(log.wait([&] { return static_cast<int>(log.frames.size()) >= 5 + i; }, 5s));
    device.produce(payload_for(device.format(), 10 + i));
  }
  ASSERT_TRUE(log.wait([&] { return log.frames.size() == 10; }, 5s));
  EXPECT_EQ(source.state(), StreamState::Streaming);
  source.stop();
  EXPECT_EQ(mismatches(log.frames[9], 14), 0);
  const auto stats = source.v4l2_statistics();
  EXPECT_EQ(stats.outages, 1u);
  EXPECT_EQ(stats.connections, 2u);
  EXPECT_EQ(stats.frames.received, 10u);
  EXPECT_EQ(stats.frames.dropped, 0u) << "the counter restarting at STREAMON is not a drop";
}

TEST(V4l2FrameSource, EnodevFromDequeueTearsDownAndReopens) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  device.fail_next_dqbuf(ENODEV);
  device.produce(payload_for(device.format(), 0));  // wakes the grabber into the failing DQBUF
  ASSERT_TRUE(log.wait([&] { return log.said({"VIDIOC_DQBUF", "ENODEV"}); }, 5s));
  ASSERT_TRUE(device.wait_streaming(5s, 2));
  device.produce(payload_for(device.format(), 1));
  ASSERT_TRUE(log.wait([&] { return !log.frames.empty(); }, 5s));
  source.stop();
  EXPECT_EQ(mismatches(log.frames[0], 1), 0);
  EXPECT_EQ(source.v4l2_statistics().outages, 1u);
}

TEST(V4l2FrameSource, TheWatchdogReportsAStallThenReopensAHungDevice) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  V4l2Options o = quick_options(c.path);
  o.restart_after = 600ms;
  Grabbing g(c, o);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  device.produce(payload_for(device.format(), 0));
  ASSERT_TRUE(log.wait([&] { return !log.frames.empty(); }, 5s));
  // The sensor falls silent: stalled after 150 ms, reopened after 600 ms.
  ASSERT_TRUE(log.wait([&] { return log.saw(StreamState::Stalled); }, 5s));
  ASSERT_TRUE(device.wait_streaming(5s, 2));
  EXPECT_TRUE(log.wait([&] { return log.said({"reopening the device"}); }, 1s));
  EXPECT_EQ(device.opens(), 2);
  device.produce(payload_for(device.format(), 1));
  ASSERT_TRUE(log.wait([&] { return log.frames.size() == 2; }, 5s));
  EXPECT_EQ(source.state(), StreamState::Streaming);
  source.stop();
  const auto stats = source.v4l2_statistics();
  EXPECT_GE(stats.restarts, 1u);
  EXPECT_EQ(stats.outages, 0u) << "a hang is not a lost device";
}

TEST(V4l2FrameSource, AGrabberWithoutSignalWaitsForOneAndBacksOffItsReopening) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  V4l2Options o = quick_options(c.path);
  o.restart_after = 300ms;
  Grabbing g(c, o);
  auto& [device, log, source] = g;
  ASSERT_TRUE(log.wait([&] { return log.said({"no frame yet", "video signal"}); }, 5s));
  // Reopened after 0.3, 0.6, 1.2 s, ...: three reopenings take 2.1 s, not 0.9 s.
  std::this_thread::sleep_for(1500ms);
  EXPECT_LE(device.opens(), 3) << "reopening does not back off";
  EXPECT_FALSE(log.wait([&] { return log.saw(StreamState::Stalled); }, 10ms)) << "a stream never started is not stalled";
  device.produce(payload_for(device.format(), 0));  // the signal comes (once streaming again)
  ASSERT_TRUE(device.wait_streaming(5s));
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!log.wait([&] { return !log.frames.empty(); }, 50ms)) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "no frame after the signal came";
    device.produce(payload_for(device.format(), 0));
  }
  source.stop();
}

TEST(V4l2FrameSource, AQueueInItsErrorStateIsReopened) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(device.wait_streaming(5s));
  device.queue_error();  // videobuf2: EIO from DQBUF, POLLERR, until stream off
  ASSERT_TRUE(device.wait_streaming(5s, 2));
  device.produce(payload_for(device.format(), 3));
  ASSERT_TRUE(log.wait([&] { return !log.frames.empty(); }, 5s));
  source.stop();
  EXPECT_EQ(mismatches(log.frames[0], 3), 0);
  EXPECT_EQ(source.v4l2_statistics().outages, 1u);
}

TEST(V4l2FrameSource, FieldsInSeparateBuffersAreRefusedNamingTheFieldOrder) {
  FakeV4l2Device::Config c;
  c.field = V4L2_FIELD_ALTERNATE;  // an analog grabber that sends one field per buffer
  Grabbing g(c);
  auto& [device, log, source] = g;
  ASSERT_TRUE(log.wait([&] { return log.said({"field order", "interleaved frames only"}); }, 5s));
  source.stop();
  EXPECT_TRUE(log.frames.empty());
}

// Each side within 16384, but 2^27 pixels in all: a driver (or a fake) that grants that is
// refused before a buffer is asked for.
TEST(V4l2FrameSource, ASizeOfMorePixelsThanAnyImageReadIsRefused) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  c.max_width = 16384;
  c.max_height = 16384;
  V4l2Options o = quick_options(c.path);
  o.width = 16384;
  o.height = 8192;
  Grabbing g(c, o);
  auto& [device, log, source] = g;
  ASSERT_TRUE(log.wait([&] { return log.said({"implausible size", "16384x8192"}); }, 5s));
  source.stop();
  EXPECT_TRUE(log.frames.empty());
}

TEST(V4l2FrameSource, StopReturnsWhileACameraOutrunsTheFrameHandling) {
  FakeV4l2Device::Config c;
  c.formats = {V4L2_PIX_FMT_GREY};
  FakeV4l2Device device(c);
  test::StreamLog log;
  V4l2FrameSource source(quick_options(c.path), device);
  source.start([](const Frame&) { std::this_thread::sleep_for(5ms); }, [&](StreamState s, const std::string& r) { log.on_stream(s, r); });
  ASSERT_TRUE(device.wait_streaming(5s));
  std::atomic<bool> flooding{true};
  std::thread sensor([&] {
    const auto payload = payload_for(device.format(), 0);
    while (flooding) device.produce(payload);  // a filled buffer is always waiting
  });
  std::this_thread::sleep_for(200ms);
  auto stopping = std::async(std::launch::async, [&] { source.stop(); });
  const bool stopped = stopping.wait_for(2s) == std::future_status::ready;
  flooding = false;  // unblocks a starved stop() so the test ends either way
  sensor.join();
  stopping.wait();
  EXPECT_TRUE(stopped) << "stop() was starved by the stream";
}

// ---- enumeration -------------------------------------------------------------------------

TEST(V4l2Devices, ListsVideoNodesInNumberOrderWithWhatTheySay) {
  const auto dir = std::filesystem::temp_directory_path() / ("evar-v4l2-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const char* name : {"video10", "video0", "video1", "video", "videoX", "vbi0", "media0"})
    std::ofstream(dir / name).put('\n');
  FakeV4l2Device::Config c;
  c.path = (dir / "video0").string();
  c.formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  FakeV4l2Device device(c);
  const auto list = list_v4l2_devices(device, dir);
  std::filesystem::remove_all(dir);
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(std::filesystem::path(list[0].path).filename(), "video0");
  EXPECT_EQ(std::filesystem::path(list[1].path).filename(), "video1");
  EXPECT_EQ(std::filesystem::path(list[2].path).filename(), "video10");
  EXPECT_EQ(list[0].card, "Scripted grabber");
  EXPECT_TRUE(list[0].can_capture);
  EXPECT_EQ(list[0].formats, (std::vector<std::uint32_t>{V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG}));
  EXPECT_TRUE(list[0].error.empty());
  EXPECT_NE(list[1].error.find("ENOENT"), std::string::npos) << list[1].error;
  EXPECT_EQ(device.open_fds(), 0);
  EXPECT_TRUE(list_v4l2_devices(device, dir / "absent").empty());
}

}  // namespace
}  // namespace evar::acquisition
