// Coarse-to-fine scoring on the device, one small read per frame (nlos_cl/search.py explains
// the search; nlos_cl/ops/fused_search.py is the host side and the NumPy twin).
//
// coarse_pair: every coarse cell (a block's centre) scored twice by score8, the same code as a
//   whole grid: on the filtered rows (exact) and on the dilated rows over the widened record
//   (bound, an upper bound of every fine cell of the block).
// Then three launches (one work group of WG items, many, one):
// select_candidates, in two steps separated by barriers:
//   1. L = the best exact score (coarse_pair leaves -inf where a block's centre is no fine
//      cell); the threshold
//      thr = L - SLACK (|L| + slack_add);
//   2. the candidate blocks (bound >= thr), compacted into `list` in coarse-index order (each
//      item counts its own contiguous share, offsets by a prefix over the items' counts);
//      list[0] = their number;
// refine_partial (every group of the device's work, not one: one group used one core of a
//   CPU and one multiprocessor of a GPU, 1/132 of an H100's):
//   3. every fine cell of every candidate block scored (rows of a block in float8 steps, work
//      units dealt round-robin over all items), each item keeping its best (value, flat
//      index), ties to the lower flat index, then each group's best: the result does not
//      depend on which item or group scored what;
// refine_finish:
//   4. the best over the groups (ties: lower flat index, as argmax over a whole map), then
//      items 0..8 score the 3 x 3 x 3 cells around it (NaN outside the grid), one row each.
//   result: [ix, iy, iz, score, candidate blocks, 0, 0, 0, 27 neighbourhood scores (dz, dy,
//   dx)], all exact in float (indices and counts below 2^24, which the host checks); ix = -1
//   when no block was a candidate (the host then scores every cell).
// Deterministic (no atomics); every score is score8's, so bit-identical to exhaustive scoring.
//
// Build options: -D N_DET -D LOG_MODE -D LOG_FLOOR (score.h) -D WG=<work-group size>
//                -D SLACK=<relative slack, float>

#include "common.h"
#include "score.h"

__kernel void coarse_pair(__global const float *signal, __global const float *dilated,
                          __global const float2 *stats, __global const float4 *spots,
                          __global const float4 *lasers,
                          __global const float2 *axis,       // the record's (path0, 1/dpath)
                          __global const float2 *wide_axis,  // the widened record's
                          const int n_bins, const int n_wide,
                          const float4 origin, const float4 step,  // the coarse grid's
                          const int nx, const int ny,
                          const int4 valid,  // per axis: coarse cells whose centre is a fine cell
                          __global float *exact, __global float *bound)  // [nz][ny][nx]
{
    const int ix0 = get_global_id(0) * 8;
    const int iy = get_global_id(1), iz = get_global_id(2);
    const float8 x = origin.x + step.x * convert_float8((int8)(ix0) + (int8)(0, 1, 2, 3, 4, 5, 6, 7));
    const float y = origin.y + step.y * (float)iy;
    const float z = origin.z + step.z * (float)iz;
    const int at = (iz * ny + iy) * nx + ix0, n = nx - ix0;
    const float8 one = (float8)(LOG_MODE ? 0.0f : 1.0f);
    const int8 inside = ((int8)(ix0) + (int8)(0, 1, 2, 3, 4, 5, 6, 7) < (int8)(valid.x))
                        & (int8)(iy < valid.y && iz < valid.z ? -1 : 0);
    // a block whose centre lies past the grid's edge is no fine cell: -inf, out of the maximum
    store8(exact + at, n, select((float8)(-INFINITY), score8(signal, stats, spots, lasers, axis,
                                                             n_bins, 0, x, y, z, one), inside));
    store8(bound + at, n, score8(dilated, stats, spots, lasers, wide_axis, n_wide, 0, x, y, z,
                                 one));
}

// (value, flat) beats (best, where): any cell beats none (where < 0); else higher, or equal at
// a lower flat index (the first maximum, as argmax over a whole map).
inline int beats(const float value, const int flat, const float best, const int where)
{
    if (flat < 0) return 0;
    if (where < 0) return 1;
    return value > best || (value == best && flat < where);
}

// Step 3 for one work unit: `chunk` (8 cells) of row (jy, jz) of candidate block `block`.
inline void score_unit(__global const float *signal, __global const float2 *stats,
                       __global const float4 *spots, __global const float4 *lasers,
                       __global const float2 *axis, const int n_bins, const float4 origin,
                       const float4 step, const int4 shape, const int4 fa, const int4 cshape,
                       const int block, const int jy, const int jz, const int chunk,
                       float *best, int *where)
{
    const int bx = block % cshape.x, by = (block / cshape.x) % cshape.y;
    const int bz = block / (cshape.x * cshape.y);
    const int iy = by * fa.y + jy, iz = bz * fa.z + jz, j0 = chunk * 8;
    if (iy >= shape.y || iz >= shape.z) return;
    const int8 ix = (int8)(bx * fa.x + j0) + (int8)(0, 1, 2, 3, 4, 5, 6, 7);
    const float8 x = origin.x + step.x * convert_float8(ix);
    const float y = origin.y + step.y * (float)iy;
    const float z = origin.z + step.z * (float)iz;
    float cells[8];
    vstore8(score8(signal, stats, spots, lasers, axis, n_bins, 0, x, y, z,
                   (float8)(LOG_MODE ? 0.0f : 1.0f)), 0, cells);
    const int row = (iz * shape.y + iy) * shape.x;
    for (int j = 0; j < 8 && j0 + j < fa.x && bx * fa.x + j0 + j < shape.x; ++j) {
        const int flat = row + bx * fa.x + j0 + j;
        if (beats(cells[j], flat, *best, *where)) { *best = cells[j]; *where = flat; }
    }
}

// Steps 1 and 2: the threshold, then the candidate blocks in coarse-index order. Returns
// their number (every item gets the same).
inline int select_blocks(__global const float *exact, __global const float *bound,
                         const int4 cshape, const float slack_add, __global int *list,
                         __local float *lval, __local int *lcount)
{
    const int w = get_local_id(0);
    const int n_coarse = cshape.x * cshape.y * cshape.z;
    const int per = (n_coarse + WG - 1) / WG;
    const int c0 = min(w * per, n_coarse), c1 = min(c0 + per, n_coarse);
    float top = -INFINITY;  // exact is -inf where the block's centre is no fine cell
    for (int c = c0; c < c1; ++c) top = fmax(top, exact[c]);
    lval[w] = top;
    barrier(CLK_LOCAL_MEM_FENCE);
    float best = -INFINITY;
    for (int j = 0; j < WG; ++j) best = fmax(best, lval[j]);
    const float thr = best - SLACK * (fabs(best) + slack_add);
    int count = 0;
    for (int c = c0; c < c1; ++c) count += bound[c] >= thr;
    lcount[w] = count;
    barrier(CLK_LOCAL_MEM_FENCE);
    int offset = 0, total = 0;
    for (int j = 0; j < WG; ++j) {
        offset += j < w ? lcount[j] : 0;
        total += lcount[j];
    }
    for (int c = c0; c < c1; ++c) {
        if (bound[c] >= thr) list[offset++] = c;
    }
    barrier(CLK_GLOBAL_MEM_FENCE | CLK_LOCAL_MEM_FENCE);
    return total;
}

__kernel __attribute__((reqd_work_group_size(WG, 1, 1)))
void select_candidates(__global const float *exact, __global const float *bound,
                       const int4 cshape,                      // blocks (coarse cells)
                       const float slack_add,                  // 1 in log mode, else 0
                       __global int *list)                     // [1 + coarse cells]
{
    __local float lval[WG];
    __local int lcount[WG];
    const int total = select_blocks(exact, bound, cshape, slack_add, list + 1, lval, lcount);
    if (get_local_id(0) == 0) list[0] = total;
}

// Step 3, spread over every work group: each keeps its best (value, flat) in partial[group].
__kernel __attribute__((reqd_work_group_size(WG, 1, 1)))
void refine_partial(__global const float *signal, __global const float2 *stats,
                    __global const float4 *spots, __global const float4 *lasers,
                    __global const float2 *axis, const int n_bins,
                    const float4 origin, const float4 step,  // the fine grid's
                    const int4 shape,                        // fine (nx, ny, nz)
                    const int4 fa,                           // cells per block (fx, fy, fz)
                    const int4 cshape,                       // blocks (coarse cells)
                    __global const int *list,                // [1 + coarse cells]: count, blocks
                    __global float *partial_value,           // [groups]
                    __global int *partial_where)             // [groups]
{
    __local float lval[WG];
    __local int lwhere[WG];
    const int w = get_local_id(0), items = get_global_size(0);
    const int chunks = (fa.x + 7) / 8;
    const int units = list[0] * fa.z * fa.y * chunks;
    float best = -INFINITY;
    int where = -1;
    for (int u = get_global_id(0); u < units; u += items) {
        const int chunk = u % chunks, jy = (u / chunks) % fa.y;
        const int jz = (u / (chunks * fa.y)) % fa.z, k = u / (chunks * fa.y * fa.z);
        score_unit(signal, stats, spots, lasers, axis, n_bins, origin, step, shape, fa, cshape,
                   list[1 + k], jy, jz, chunk, &best, &where);
    }
    lval[w] = best;
    lwhere[w] = where;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (w == 0) {
        for (int j = 1; j < WG; ++j) {
            if (beats(lval[j], lwhere[j], best, where)) { best = lval[j]; where = lwhere[j]; }
        }
        partial_value[get_group_id(0)] = best;
        partial_where[get_group_id(0)] = where;
    }
}

// Step 4: the best over the groups (ties: lower flat index), its 3 x 3 x 3 neighbourhood.
__kernel __attribute__((reqd_work_group_size(WG, 1, 1)))
void refine_finish(__global const float *signal, __global const float2 *stats,
                   __global const float4 *spots, __global const float4 *lasers,
                   __global const float2 *axis, const int n_bins,
                   const float4 origin, const float4 step, const int4 shape,
                   __global const int *list, __global const float *partial_value,
                   __global const int *partial_where, const int groups,
                   __global float *result)                  // [8 + 27]
{
    const int w = get_local_id(0);
    float best = -INFINITY;
    int where = -1;
    for (int j = 0; j < groups; ++j) {
        if (beats(partial_value[j], partial_where[j], best, where)) {
            best = partial_value[j];
            where = partial_where[j];
        }
    }
    const int ix = where < 0 ? -1 : where % shape.x;
    const int iy = where < 0 ? 0 : (where / shape.x) % shape.y;
    const int iz = where < 0 ? 0 : where / (shape.x * shape.y);
    if (w == 0) {
        result[0] = (float)ix; result[1] = (float)iy; result[2] = (float)iz;
        result[3] = best; result[4] = (float)list[0];
        result[5] = result[6] = result[7] = 0.0f;
    }
    if (w < 9) {  // row (dz, dy) of the neighbourhood: cells ix - 1 .. ix + 1
        const int ry = iy + w % 3 - 1, rz = iz + w / 3 - 1;
        const int row_inside = where >= 0 && ry >= 0 && ry < shape.y && rz >= 0 && rz < shape.z;
        float cells[8] = {NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN};
        if (row_inside) {
            const int8 cx = (int8)(ix - 1) + (int8)(0, 1, 2, 3, 4, 5, 6, 7);
            const float8 x = origin.x + step.x * convert_float8(cx);
            const float y = origin.y + step.y * (float)ry;
            const float z = origin.z + step.z * (float)rz;
            vstore8(score8(signal, stats, spots, lasers, axis, n_bins, 0, x, y, z,
                           (float8)(LOG_MODE ? 0.0f : 1.0f)), 0, cells);
        }
        for (int j = 0; j < 3; ++j) {
            const int inside = row_inside && ix - 1 + j >= 0 && ix - 1 + j < shape.x;
            result[8 + 3 * w + j] = inside ? cells[j] : NAN;
        }
    }
}
