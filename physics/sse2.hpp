#pragma once

// SSE2 where the processor has it (every x86-64 does), for the few kernels the discrete step
// runs on every sphere. Each such kernel keeps its plain reference beside it, and the tests
// run both in the same binary and compare them bit for bit
// (tests/physics/discrete/kernels_test.cpp). KUGEL_NO_SSE2 (a CMake option, on in the dev
// preset) builds the engine on the plain references alone.
#if defined(__SSE2__) && !defined(KUGEL_NO_SSE2)
#define KUGEL_SSE2 1
#include <emmintrin.h>
#endif
