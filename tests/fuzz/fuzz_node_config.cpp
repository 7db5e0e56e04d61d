// node.json, the bedside node's configuration.
#include "fuzz_input.hpp"
#include "node_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = evar::fuzz::write_file("node.json", {data, size});
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::app::read_node_config(path); });
  return 0;
}
