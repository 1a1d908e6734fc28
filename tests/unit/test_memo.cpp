// core/memo.h: a computation runs once per key until the memo is full, then
// the memo starts over; every value is the one computed for its own key.
#include "core/memo.h"

#include <gtest/gtest.h>

#include <string>

using namespace theia;

TEST(BoundedMemo, ComputesOncePerKeyAndStartsOverWhenFull) {
  BoundedMemo<int, std::string> memo(3);
  int computed = 0;
  auto get = [&](int k) { return memo.get(k, [&] { ++computed; return std::to_string(k * k); }); };
  EXPECT_EQ(get(2), "4");
  EXPECT_EQ(get(3), "9");
  EXPECT_EQ(get(2), "4");
  EXPECT_EQ(computed, 2);
  EXPECT_EQ(get(4), "16");
  EXPECT_EQ(computed, 3);
  // Full (3 keys): a fourth clears the memo, so 2 is computed again.
  EXPECT_EQ(get(5), "25");
  EXPECT_EQ(get(2), "4");
  EXPECT_EQ(computed, 5);
  EXPECT_EQ(get(5), "25");
  EXPECT_EQ(computed, 5);
}
