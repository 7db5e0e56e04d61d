// scene.json with the files it names: parts are scene.json, aorta.stl, aorta.centerline.mrk.json,
// landmarks.mrk.json (split at "--8<--" lines).
#include "evar/geometry/scene.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto parts = evar::fuzz::split_parts(data, size, 4);
  const auto scene = evar::fuzz::write_file("scene/scene.json", parts[0]);
  evar::fuzz::write_file("scene/aorta.stl", parts[1]);
  evar::fuzz::write_file("scene/aorta.centerline.mrk.json", parts[2]);
  evar::fuzz::write_file("scene/landmarks.mrk.json", parts[3]);
  evar::fuzz::expect_rejection_as_input_error([&] { (void)evar::geometry::load_scene(scene); });
  return 0;
}
