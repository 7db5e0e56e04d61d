#pragma once
// The message a refusal carries: tests assert that bad input is refused by name.
#include <string>
#include <utility>

#include "evar/base/input_error.hpp"

namespace evar::test {

/// What `call` throws as an E (its what()), or `none` when it returns normally.
template <class E = base::InputError, class F>
std::string error_message(F&& call, std::string none = "no error") {
  try {
    std::forward<F>(call)();
  } catch (const E& e) {
    return e.what();
  }
  return none;
}

}  // namespace evar::test
