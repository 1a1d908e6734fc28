// Heap allocations made by the calling thread, counted by the unit-test
// binary's replacement of the global operator new (allocation_count.cpp):
// "does not allocate per token" tested by a count, which a slow or loaded
// machine cannot fail as it fails a time limit.
#pragma once

#include <cstdint>

namespace theia::test {
uint64_t thread_allocations();
}  // namespace theia::test
