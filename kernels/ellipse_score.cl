// Ellipse scoring (paper Section 2.1 and 3.2): a grid cell c lies on detector i's ellipse of
// hidden path p_i = |c - O| + |c - spot_i|; its likelihood under detector i is the filtered
// signal at that path (linear interpolation between bin centres, 0 outside the record,
// negatives clipped to 0), normalised by the row maximum so products stay in float32 range.
// The joint likelihood is the product over detectors, or (LOG_MODE) the sum of
// log(max(v, LOG_FLOOR)), which stays finite for many detectors.
//
// A work item owns 8 consecutive cells along x, in float8 arithmetic with explicit gathers:
// measured on PoCL 4.5x faster than one cell per work item, whose scalar gathers kept PoCL
// from vectorizing across work items.
//
// A grid whose score map would not fit in one device allocation is scored in slabs of planes
// (or of rows, for a single plane); each cell is computed exactly as in one piece.
//
// Build options: -D N_DET=<detectors> -D LOG_MODE=0|1 -D LOG_FLOOR=<float>

#include "common.h"

__kernel void ellipse_score(__global const float *signal,   // [N_DET][n_bins]
                            __global const float2 *stats,   // [N_DET] (row max, mean square)
                            __global const float4 *spots,   // [N_DET] detector spots
                            const float4 laser,
                            __global const float2 *axis,    // [N_DET] (path at bin-0 centre, 1 / path per bin)
                            const int n_bins,
                            const float4 origin, const float4 step,
                            const int nx, const int ny,     // ny: rows in this slab
                            const int iy0, const int iz0,   // the slab's first row and plane
                            __global float *score)          // [slab planes][ny][nx]
{
    const int ix0 = get_global_id(0) * 8;
    const int iy = iy0 + get_global_id(1), iz = iz0 + get_global_id(2);  // in the whole grid
    const float8 x = origin.x + step.x * convert_float8((int8)(ix0) + (int8)(0, 1, 2, 3, 4, 5, 6, 7));
    const float y = origin.y + step.y * (float)iy;
    const float z = origin.z + step.z * (float)iz;
    // sqrt of a dot product, not distance(): PoCL's overflow-safe distance() is much slower.
    const float8 lx = x - laser.x;
    const float lyz = (y - laser.y) * (y - laser.y) + (z - laser.z) * (z - laser.z);
    const float8 r1 = sqrt(fma(lx, lx, (float8)(lyz)));
#if LOG_MODE
    float8 joint = (float8)(0.0f);
#else
    float8 joint = (float8)(1.0f);
#endif
    for (int d = 0; d < N_DET; ++d) {
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
    __global float *out = score + (get_global_id(2) * ny + get_global_id(1)) * nx + ix0;
    if (ix0 + 8 <= nx) {
        vstore8(joint, 0, out);
    } else {  // the row's last, partial block
        float cells[8];
        vstore8(joint, 0, cells);
        for (int j = 0; ix0 + j < nx; ++j) out[j] = cells[j];
    }
}
