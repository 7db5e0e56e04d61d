// The C-arm link receiver that serial and USB share, driven directly with bytes and a
// simulated clock: a link that spews garbage is reported at once, then summed into at
// most one notice per kNoticeInterval, so it cannot flood the log or the screen,
// and good samples in between still arrive.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "evar/acquisition/carm_link_protocol.hpp"
#include "carm_link_receiver.hpp"

using namespace evar::acquisition;
using namespace std::chrono_literals;

namespace {

std::vector<std::uint8_t> good_sample(std::uint16_t sequence, std::int64_t t_ns) {
  carm_link::GeometryMessage m;
  m.sequence = sequence;
  m.state.device_time_ns = t_ns;
  m.state.primary_deg = 30.0;
  m.state.sid_mm = 1200.0;
  m.state.sod_mm = 800.0;
  return carm_link::encode(m);
}

}  // namespace

TEST(CArmLinkReceiver, ContinuousGarbageGivesOneNoticeAtOnceThenOneSummaryPerInterval) {
  CArmLinkReceiver rx("serial /dev/ttyX", 1000ms);
  std::vector<std::string> error_notices;
  std::vector<StreamState> changes;
  int samples = 0;
  rx.set_callbacks([&](const CArmState&) { ++samples; }, [&](StreamState s, const std::string&) { changes.push_back(s); },
                   [&](const LinkNotice& notice) {
                     EXPECT_EQ(notice.kind, LinkNotice::Kind::BadFrames);
                     error_notices.push_back(notice.text);
                   });
  rx.connected();
  const auto t0 = CArmLinkReceiver::Clock::time_point{} + 1h;
  const std::vector<std::uint8_t> garbage{0x00, 0x03, 0x41, 0x42, 0x00};  // a frame too short to be a message
  // 25 s of a link that sends a bad frame and a good sample every 10 ms.
  std::uint16_t seq = 0;
  for (int k = 0; k < 2500; ++k) {
    const auto now = t0 + k * 10ms;
    rx.received(garbage, now);
    rx.received(good_sample(seq++, 1'000'000'000LL + k * 10'000'000LL), now);
    if (k % 10 == 0) rx.tick(now);
  }
  EXPECT_EQ(samples, 2500);
  EXPECT_EQ(rx.statistics().link.errors(), 2500u);
  // At 0 s, 10 s and 20 s: three notices for 2500 bad frames, not 2500.
  ASSERT_EQ(error_notices.size(), 3u);
  EXPECT_TRUE(error_notices[0].starts_with("C-arm link serial /dev/ttyX: ")) << error_notices[0];
  EXPECT_NE(error_notices[0].find("(1 bad frames so far)"), std::string::npos) << error_notices[0];
  // News, not a change of state: the link went from connecting to streaming, and stayed.
  EXPECT_EQ(changes, (std::vector<StreamState>{StreamState::Connecting, StreamState::Streaming}));
  EXPECT_NE(error_notices[1].find("1000 bad frames since the last report (1001 bad frames so far)"), std::string::npos)
      << error_notices[1];
  EXPECT_NE(error_notices[1].find("the last: "), std::string::npos) << error_notices[1];
  // What the last burst left unreported comes with the next tick after the interval, even
  // when the garbage has stopped.
  rx.tick(t0 + 40s);
  ASSERT_EQ(error_notices.size(), 4u);
  EXPECT_NE(error_notices[3].find("499 bad frames since the last report (2500 bad frames so far)"), std::string::npos)
      << error_notices[3];
  rx.tick(t0 + 60s);
  EXPECT_EQ(error_notices.size(), 4u);  // nothing new, nothing said
}

TEST(CArmLinkReceiver, AStatusTheCArmRepeatsIsReportedOncePerInterval) {
  CArmLinkReceiver rx("usb 1209:ea01", 1000ms);
  std::vector<std::string> notices;
  rx.set_callbacks([](const CArmState&) {}, nullptr, [&](const LinkNotice& notice) {
    EXPECT_EQ(notice.kind, LinkNotice::Kind::CArmStatus);
    notices.push_back(notice.text);
  });
  rx.connected();
  const auto t0 = CArmLinkReceiver::Clock::time_point{} + 1h;
  carm_link::StatusMessage warning;
  warning.level = carm_link::StatusLevel::Warning;
  warning.text = "tube temperature high";
  for (int k = 0; k < 2500; ++k) {  // every 10 ms for 25 s
    warning.sequence = static_cast<std::uint16_t>(k);
    rx.received(carm_link::encode(warning), t0 + k * 10ms);
  }
  ASSERT_EQ(notices.size(), 3u);  // at 0, 10 and 20 s
  EXPECT_EQ(notices[0], "C-arm warning: tube temperature high");
  warning.text = "collimator moving";  // something new is news at once
  rx.received(carm_link::encode(warning), t0 + 25s + 10ms);
  ASSERT_EQ(notices.size(), 4u);
  EXPECT_EQ(notices[3], "C-arm warning: collimator moving");
}

// A C-arm that repeats two warnings in turn, every message, says each once per interval
// (before the fix only the last text was remembered: each turn was news, ten a second).
// A peer sending ever new texts is held to kMaxStatusTexts notices per interval.
TEST(CArmLinkReceiver, WarningsTakingTurnsAreReportedOncePerIntervalEachAndNewTextsAreCapped) {
  CArmLinkReceiver rx("usb 1209:ea01", 1000ms);
  std::vector<std::string> notices;
  rx.set_callbacks([](const CArmState&) {}, nullptr, [&](const LinkNotice& notice) { notices.push_back(notice.text); });
  rx.connected();
  const auto t0 = CArmLinkReceiver::Clock::time_point{} + 1h;
  carm_link::StatusMessage warning;
  warning.level = carm_link::StatusLevel::Warning;
  for (int k = 0; k < 2500; ++k) {  // every 10 ms for 25 s, two texts in turn
    warning.sequence = static_cast<std::uint16_t>(k);
    warning.text = k % 2 ? "collimator moving" : "tube temperature high";
    rx.received(carm_link::encode(warning), t0 + k * 10ms);
  }
  ASSERT_EQ(notices.size(), 6u);  // each at 0, 10 and 20 s
  EXPECT_EQ(std::count(notices.begin(), notices.end(), "C-arm warning: collimator moving"), 3);

  notices.clear();
  const auto t1 = t0 + 60s;
  for (int k = 0; k < 100; ++k) {  // 100 different texts within a second
    warning.sequence = static_cast<std::uint16_t>(k);
    warning.text = "fault " + std::to_string(k);
    rx.received(carm_link::encode(warning), t1 + k * 10ms);
  }
  EXPECT_EQ(notices.size(), CArmLinkReceiver::kMaxStatusTexts);
  EXPECT_EQ(rx.statistics().statuses_not_reported, 100u - CArmLinkReceiver::kMaxStatusTexts);
}
