#pragma once
// CHECK: a broken internal invariant. User errors and network errors are never CHECKs.
#include <cstdio>
#include <cstdlib>

#define RAYFARM_CHECK(cond, msg)                                                            \
  do {                                                                                      \
    if (!(cond)) {                                                                          \
      std::fprintf(stderr, "%s:%d: CHECK failed: %s (%s)\n", __FILE__, __LINE__, #cond, msg); \
      std::abort();                                                                         \
    }                                                                                       \
  } while (0)
