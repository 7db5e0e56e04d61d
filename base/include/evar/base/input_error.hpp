#pragma once
// The error every reader and validator throws for bad outside data. Its message names
// the file, the field or byte, and what is wrong, so the user can fix the input.
#include <stdexcept>
#include <string>

namespace evar::base {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace evar::base
