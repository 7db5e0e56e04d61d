#include <cstdio>
#include <string>
#include <vector>

#include "evar/app/cli.hpp"
#include "heap_reuse.hpp"

int main(int argc, char** argv) {
  if (evar::app::keep_freed_memory_for_reuse() == evar::app::HeapReuse::refused)
    std::fputs("evarnode: note: the C library refused the heap settings (mallopt); frames will be slower\n", stderr);
  std::vector<std::string> args(argv + 1, argv + argc);
  return evar::app::run_cli(args);
}
