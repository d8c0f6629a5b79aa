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
#include "score.h"

__kernel void ellipse_score(__global const float *signal,   // [detectors][n_bins]
                            __global const float2 *stats,   // [detectors] (row max, mean square)
                            __global const float4 *spots,   // [detectors] detector spots
                            __global const float4 *lasers,
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
    const float8 joint = score8(signal, stats, spots, lasers, axis, n_bins, det0, x, y, z,
                                start8(out, n, accumulate));
    store8(out, n, joint);
}

__kernel void ellipse_score_blocks(__global const float *signal, __global const float2 *stats,
                                   __global const float4 *spots, __global const float4 *lasers,
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
    float8 joint = score8(signal, stats, spots, lasers, axis, n_bins, det0, x, y, z,
                          start8(out, n, accumulate));
    const int row_inside = iy >= 0 && iy < shape.y && iz >= 0 && iz < shape.z;
    const int8 inside = (ix >= (int8)(0)) & (ix < (int8)(shape.x)) & (int8)(row_inside ? -1 : 0);
    joint = select((float8)(-INFINITY), joint, inside);
    store8(out, n, joint);
}
