// The one line a user sees for an error (core/log.h error_line).
#include "core/log.h"

#include <gtest/gtest.h>

using namespace theia;

TEST(ErrorLine, LocatedMessagesKeepTheirOwnErrorAndOthersGetOne) {
  EXPECT_EQ(error_line("scene.pbrt:3:76: error: bad number"), "scene.pbrt:3:76: error: bad number");
  EXPECT_EQ(error_line("/a/b.ply: error: vertex element without x"), "/a/b.ply: error: vertex element without x");
  EXPECT_EQ(error_line("--spp must be positive, got -1"), "error: --spp must be positive, got -1");
  // "error:" inside the text of an unlocated message is not a location.
  EXPECT_EQ(error_line("cannot rename x: error: disk full"), "error: cannot rename x: error: disk full");
}
