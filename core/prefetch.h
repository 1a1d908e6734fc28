// A cache line asked for ahead of its use.
#pragma once

namespace theia {

// __builtin_prefetch, except that GCC may drop that one where the address
// comes from a vector's or table's own pointer (it did so for the path
// pool's cold tables and for shading's triangle corners, which cost the
// shade stage a tenth); on x86-64 this instruction always stays.
inline void prefetch_line(const void* p) {
#if defined(__x86_64__)
  asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#else
  __builtin_prefetch(p);
#endif
}

}  // namespace theia
