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
// Detector tiles: one launch scores N_DET detectors starting at det0; with `accumulate` it
// continues the joint likelihood already in the output (multiplies or adds onto it, in the
// same order as one pass would: the result is bit-identical). Many detectors are scored tile
// by tile, so the rows of one tile stay in cache while every cell reads them (1,024 rows of
// 4,096 bins are 16 MiB: scored in one pass, every cell would walk all of them).
//
// A grid whose score map would not fit in one device allocation is scored in slabs of planes
// (or of rows, for a single plane); each cell is computed exactly as in one piece.
// ellipse_score_blocks scores tiles of cells at given grid indices (coarse-to-fine search,
// nlos_cl/search.py); cells outside the grid get -INFINITY.
//
// Build options: -D N_DET=<detectors per launch> -D LOG_MODE=0|1 -D LOG_FLOOR=<float>

#include "common.h"

// The joint likelihood of 8 cells at (x, y, z), detectors det0 .. det0 + N_DET - 1, on top of
// `joint` (the previous tiles' result, or 1 / 0).
inline float8 score8(__global const float *signal, __global const float2 *stats,
                     __global const float4 *spots, const float4 laser,
                     __global const float2 *axis, const int n_bins, const int det0,
                     const float8 x, const float y, const float z, float8 joint)
{
    // sqrt of a dot product, not distance(): PoCL's overflow-safe distance() is much slower.
    const float8 lx = x - laser.x;
    const float lyz = (y - laser.y) * (y - laser.y) + (z - laser.z) * (z - laser.z);
    const float8 r1 = sqrt(fma(lx, lx, (float8)(lyz)));
    for (int k = 0; k < N_DET; ++k) {
        const int d = det0 + k;
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

__kernel void ellipse_score(__global const float *signal,   // [detectors][n_bins]
                            __global const float2 *stats,   // [detectors] (row max, mean square)
                            __global const float4 *spots,   // [detectors] detector spots
                            const float4 laser,
                            __global const float2 *axis,    // [detectors] (path at bin-0 centre, 1 / path per bin)
                            const int n_bins,
                            const float4 origin, const float4 step,
                            const int nx, const int ny,     // ny: rows in this slab
                            const int iy0, const int iz0,   // the slab's first row and plane
                            const int det0, const int accumulate,
                            __global float *score)          // [slab planes][ny][nx]
{
    const int ix0 = get_global_id(0) * 8;
    const int iy = iy0 + get_global_id(1), iz = iz0 + get_global_id(2);  // in the whole grid
    const float8 x = origin.x + step.x * convert_float8((int8)(ix0) + (int8)(0, 1, 2, 3, 4, 5, 6, 7));
    const float y = origin.y + step.y * (float)iy;
    const float z = origin.z + step.z * (float)iz;
    __global float *out = score + (get_global_id(2) * ny + get_global_id(1)) * nx + ix0;
    const int n = nx - ix0;
    const float8 joint = score8(signal, stats, spots, laser, axis, n_bins, det0, x, y, z,
                                start8(out, n, accumulate));
    store8(out, n, joint);
}

__kernel void ellipse_score_blocks(__global const float *signal, __global const float2 *stats,
                                   __global const float4 *spots, const float4 laser,
                                   __global const float2 *axis, const int n_bins,
                                   const float4 origin, const float4 step,
                                   const int4 shape,              // the grid's (nx, ny, nz)
                                   __global const int4 *blocks,   // first cell (ix, iy, iz) of each tile
                                   const int4 tile,               // cells per tile (tx, ty, tz)
                                   const int det0, const int accumulate,
                                   __global float *score)         // [blocks][tz][ty][tx]
{
    const int ix0 = get_global_id(0) * 8;
    const int jy = get_global_id(1);
    const int b = get_global_id(2) / tile.z, jz = get_global_id(2) % tile.z;
    const int4 first = blocks[b];
    const int iy = first.y + jy, iz = first.z + jz;
    const int8 ix = (int8)(first.x + ix0) + (int8)(0, 1, 2, 3, 4, 5, 6, 7);
    const float8 x = origin.x + step.x * convert_float8(ix);
    const float y = origin.y + step.y * (float)iy;
    const float z = origin.z + step.z * (float)iz;
    __global float *out = score + ((b * tile.z + jz) * tile.y + jy) * tile.x + ix0;
    const int n = tile.x - ix0;
    float8 joint = score8(signal, stats, spots, laser, axis, n_bins, det0, x, y, z,
                          start8(out, n, accumulate));
    const int row_inside = iy >= 0 && iy < shape.y && iz >= 0 && iz < shape.z;
    const int8 inside = (ix >= (int8)(0)) & (ix < (int8)(shape.x)) & (int8)(row_inside ? -1 : 0);
    joint = select((float8)(-INFINITY), joint, inside);
    store8(out, n, joint);
}
