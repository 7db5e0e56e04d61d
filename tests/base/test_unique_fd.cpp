// The owned file descriptor: closed exactly once, by whoever holds it last.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <utility>

#include "evar/base/unique_fd.hpp"

namespace {

using evar::base::UniqueFd;

bool is_open(int fd) { return ::fcntl(fd, F_GETFD) != -1; }

TEST(UniqueFd, ClosesWhatItHoldsWhenItGoesAndWhenItTakesAnother) {
  int a = -1, b = -1;
  {
    UniqueFd fd(::open("/dev/null", O_RDONLY | O_CLOEXEC));
    ASSERT_TRUE(fd);
    a = fd.get();
    EXPECT_TRUE(is_open(a));
    fd.reset(::open("/dev/null", O_RDONLY | O_CLOEXEC));
    b = fd.get();
    EXPECT_TRUE(is_open(b));
    if (a != b) {  // the kernel may hand the same number back
      EXPECT_FALSE(is_open(a));
    }
  }
  EXPECT_FALSE(is_open(b));
  EXPECT_FALSE(UniqueFd());
  EXPECT_FALSE(UniqueFd(-1));
}

TEST(UniqueFd, AMoveHandsItOnAndAReleaseGivesItUpOpen) {
  UniqueFd first(::open("/dev/null", O_RDONLY | O_CLOEXEC));
  const int n = first.get();
  UniqueFd second(std::move(first));
  EXPECT_FALSE(first);  // NOLINT(bugprone-use-after-move): the moved-from state is the point
  EXPECT_EQ(second.get(), n);
  UniqueFd third;
  third = std::move(second);
  EXPECT_EQ(third.get(), n);
  const int raw = third.release();
  EXPECT_FALSE(third);
  EXPECT_TRUE(is_open(raw));
  ::close(raw);
}

}  // namespace
