// Helpers shared by more than one kernel. The host pastes this file in place of the line
// `#include "common.h"` (no -I path: works on every OpenCL implementation and in the wheel).

#ifndef NLOS_COMMON_H
#define NLOS_COMMON_H

// erf by Abramowitz & Stegun 7.1.26 (|error| <= 1.5e-7; 4.7e-7 measured in float32): plain
// arithmetic and exp, so it vectorizes. PoCL's builtin erf ran at 0.44 G lanes/s on the 2-core
// CPU against 1.63 for this one; it also gives the same result on every device. The error is
// smooth in x, so adjacent bin edges err alike and their difference errs far less. One body
// for any float type T: erf16 (the forward model's bins) and erf1 (plate_model's taps: PoCL
// 3.0's LLVM 14 crashed building a two-lane use of erf16 there, "Cannot emit physreg copy").
#define AS_ERF_BODY(T, x)                                                                     \
    const T ax = fabs(x);                                                                    \
    const T t = 1.0f / fma(0.3275911f, ax, 1.0f);                                           \
    const T poly = t * fma(t, fma(t, fma(t, fma(t, 1.061405429f, -1.453152027f),             \
                                         1.421413741f), -0.284496736f), 0.254829592f);     \
    return copysign(1.0f - poly * exp(-ax * ax), x)

inline float16 erf16(const float16 x) { AS_ERF_BODY(float16, x); }
inline float erf1(const float x) { AS_ERF_BODY(float, x); }

// Eight loads from one row: PoCL emits no hardware gathers, but the float8 arithmetic around
// them still vectorizes.
inline float8 gather8(__global const float *row, const int8 i)
{
    return (float8)(row[i.s0], row[i.s1], row[i.s2], row[i.s3],
                    row[i.s4], row[i.s5], row[i.s6], row[i.s7]);
}

#endif
