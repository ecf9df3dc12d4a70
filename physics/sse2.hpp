#pragma once

// SSE2 where the processor has it (every x86-64 does), for the few comparisons the discrete
// step makes of every sphere; KUGEL_NO_SSE2 (a CMake option, on in the dev preset) builds
// their portable scalar versions instead, which give the same results: the sanitized tests,
// golden hashes among them, check that.
#if defined(__SSE2__) && !defined(KUGEL_NO_SSE2)
#define KUGEL_SSE2 1
#include <emmintrin.h>
#endif
