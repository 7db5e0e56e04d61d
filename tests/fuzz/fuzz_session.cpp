// A recorded session's manifest and streams: parts are session.json, frames/index.csv,
// carm.csv, registration.json (split at "--8<--" lines).
#include "evar/session/session.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto parts = evar::fuzz::split_parts(data, size, 4);
  const auto dir = evar::fuzz::scratch() / "session";
  evar::fuzz::write_file("session/session.json", parts[0]);
  evar::fuzz::write_file("session/frames/index.csv", parts[1]);
  evar::fuzz::write_file("session/carm.csv", parts[2]);
  evar::fuzz::write_file("session/registration.json", parts[3]);
  // Frame files the index may name (images are read only on demand, not here).
  evar::fuzz::write_file("session/frames/000001.png", {});
  evar::fuzz::write_file("session/frames/000002.png", {});
  evar::fuzz::expect_rejection_as_input_error([&] { (void)evar::session::read_session(dir); });
  return 0;
}
