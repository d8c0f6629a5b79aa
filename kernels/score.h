// The scoring arithmetic shared by every kernel that scores grid cells (ellipse_score.cl,
// fused_search.cl). The host pastes this file in place of `#include "score.h"`, after
// common.h. One copy of the code is what makes coarse-to-fine scoring bit-identical to scoring
// every cell: each cell's score is computed by the same operations, whichever kernel runs them.
// Build options: -D N_DET=<detectors per call> -D LOG_MODE=0|1 -D LOG_FLOOR=<float>
//                -D PAIRED=0|1 (0: lasers[0] is every detector's laser spot; 1: lasers[d] is
//                detector d's own: confocal and paired captures)

#ifndef NLOS_SCORE_H
#define NLOS_SCORE_H

// |c - p| for 8 cells c = (x, y, z): sqrt of a dot product, not distance(): PoCL's
// overflow-safe distance() is much slower.
inline float8 leg8(const float4 p, const float8 x, const float y, const float z)
{
    const float8 px = x - p.x;
    const float pyz = (y - p.y) * (y - p.y) + (z - p.z) * (z - p.z);
    return sqrt(fma(px, px, (float8)(pyz)));
}

// The joint likelihood of 8 cells at (x, y, z), detectors det0 .. det0 + N_DET - 1, on top of
// `joint` (the previous tiles' result, or 1 / 0).
inline float8 score8(__global const float *signal, __global const float2 *stats,
                     __global const float4 *spots, __global const float4 *lasers,
                     __global const float2 *axis, const int n_bins, const int det0,
                     const float8 x, const float y, const float z, float8 joint)
{
#if !PAIRED
    const float8 r1 = leg8(lasers[0], x, y, z);  // one laser spot: its leg is shared
#endif
    for (int k = 0; k < N_DET; ++k) {
        const int d = det0 + k;
#if PAIRED
        const float8 r1 = leg8(lasers[d], x, y, z);
#endif
        const float4 spot = spots[d];
        const float2 ax = axis[d];
        const float8 sx = x - spot.x;
        const float syz = (y - spot.y) * (y - spot.y) + (z - spot.z) * (z - spot.z);
        const float8 u = (r1 + sqrt(fma(sx, sx, (float8)(syz))) - ax.x) * ax.y;  // fractional bin
        const float8 fu = floor(u);
        const float8 t = u - fu;
        const int8 i0 = convert_int8(fu);
        // Vector bounds (not scalar ones, which the spec also allows): oclgrind 21.10 evaluates
        // integer clamp(int8, int, int) wrongly.
        const int8 last = (int8)(n_bins - 1), zero = (int8)(0);
        const int8 c0 = clamp(i0, zero, last), c1 = clamp(i0 + 1, zero, last);
        __global const float *row = signal + d * n_bins;
        // A neighbour outside the record counts as 0 (select keeps the lane where the mask is set).
        const float8 v0 = select((float8)(0.0f), gather8(row, c0), c0 == i0);
        const float8 v1 = select((float8)(0.0f), gather8(row, c1), c1 == i0 + 1);
        const float peak = stats[d].x;
        const float8 v = (peak > 0.0f) ? fmax(mix(v0, v1, t), 0.0f) * (1.0f / peak) : (float8)(0.0f);
#if LOG_MODE
        joint += log(fmax(v, (float8)(LOG_FLOOR)));
#else
        joint *= v;
#endif
    }
    return joint;
}

inline float8 start8(__global const float *out, const int n, const int accumulate)
{
    if (!accumulate) return (float8)(LOG_MODE ? 0.0f : 1.0f);
    float cells[8];
    for (int j = 0; j < 8; ++j) cells[j] = (j < n) ? out[j] : 0.0f;
    return vload8(0, cells);
}

inline void store8(__global float *out, const int n, const float8 joint)
{
    if (n >= 8) {
        vstore8(joint, 0, out);
    } else {  // a row's last, partial block
        float cells[8];
        vstore8(joint, 0, cells);
        for (int j = 0; j < n; ++j) out[j] = cells[j];
    }
}

#endif
