// The model fit's plates evaluated on the device (nlos_cl/ops/plate_model.py): the host model of
// nlos_cl/localization/model/forward/batch.py (its float64 NumPy twin) in two launches, so that an LM
// residual or a whole Jacobian's plates cost one launch pair and one read instead of ~100 NumPy
// passes.
//
//   plate_stats: one work group per statistics row r (a plate whose cell statistics some plate
//                uses: its own, or a Jacobian's unmoved plate): each lattice cell's 2 x 2 Gauss
//                points' weighted path variance over the statistics spots, the shared blur^2
//                (BLUR_SHARE of the lit cells' mean variance), each cell's pull-in keep =
//                sqrt(1 - blur^2 / var) and the path shift at each statistics spot (the part of
//                the cells' mean-path offset the pulled-in points lose). batch._cell_statistics.
//   plate_hist:  one work group per (plate b, detector d): the pulled-in points' paths and
//                weights (batch._paths), split linearly between the two sub-bins around each
//                path and summed in 32-bit fixed point with integer atomics (the sum does not
//                depend on the order: bit-identical run after run), then correlated with the
//                bin-integrated pulse per sub-bin phase (deposit.deposit_bins).
//
// Precision (float32): a path is ~5 m, so its float32 ulp (0.5 um) would be ~2e-4 of a sub-bin.
// Paths are therefore never formed whole: the host passes each (plate, detector) the path of
// the plate's centre relative to the window's first sub-bin (float64 there), and the kernel adds
// each point's path difference from the centre, r' - r = (2 a.e + e.e) / (r' + r) for a leg a
// moved by e (exact to float32's relative precision of the difference, not of the path). The
// cell statistics use the same form around each cell's centre.
//
// Laser spots: one per detector (and per statistics spot), so one laser spot for all
// (replicated by the host), a confocal scan (each spot its own) and paired layouts alike.
// Rows: float8 (x, y, z, width, height, yaw, 0, 0). Build options: -D NU, NV (the lattice),
// -D OS (sub-bins per bin), -D WG (the work group size: a power of two), -D BLUR_SHARE,
// -D GAUSS_2 (plate.py's constants).

#include "common.h"

#define CELLS (NU * NV)
#define POINTS (4 * CELLS)  // in local memory: the host allows at most MAX_CELLS cells

// Points and vectors are float4s with w = 0, never float3s: Intel's CPU OpenCL 2024 vectorizer
// returned float3 values wrong in all lanes but some (-cl-opt-disable gave the right numbers).
// A plate's frame, as plain vectors:
// its centre x, normal, the unit vector across it, its cells' edge vectors eu (across) and
// ev (up: plate.UP is z), and its width and height (batch._cells).
#define FRAME_OF(row) \
    const float4 f_x = (float4)((row).s012, 0.0f); \
    const float4 f_normal = (float4)(cos((row).s5), sin((row).s5), 0.0f, 0.0f); \
    const float4 f_across = (float4)(-sin((row).s5), cos((row).s5), 0.0f, 0.0f); \
    const float f_w = (row).s3, f_h = (row).s4; \
    const float4 f_eu = f_across * (f_w / NU), f_ev = (float4)(0.0f, 0.0f, f_h / NV, 0.0f)

// Offset of cell c's centre from the plate's centre (batch._cells' order: u outer, v inner).
inline float4 cell_offset(const float4 across, const float w, const float h, const int c)
{
    const int i = c / NV, j = c % NV;
    const float u = ((i + 0.5f) / NU - 0.5f) * w;
    const float v = ((j + 0.5f) / NV - 0.5f) * h;
    return u * across + (float4)(0.0f, 0.0f, v, 0.0f);
}

// Gauss point q's offset from its cell's centre (batch._gauss_offsets' order: su outer).
inline float4 gauss_offset(const float4 eu, const float4 ev, const int q)
{
    const float su = (q < 2) ? -1.0f : 1.0f, sv = (q & 1) ? 1.0f : -1.0f;
    return GAUSS_2 * (su * eu + sv * ev);
}

// |a + e| - |a| without forming either length's rounding: (2 a.e + e.e) / (|a + e| + |a|).
inline float leg_change(const float4 a, const float ra, const float4 e, const float rae)
{
    return (2.0f * dot(a, e) + dot(e, e)) / (rae + ra);
}

// One point's weight to spot s (batch._paths): |v1y| (n.(O - X))+ / r1^4 x |v2y| (n.(S - X))+
// / r2^4 x area, where v1 = P - O and v2 = S - P (the relay wall is y = 0).
inline float point_weight(const float4 v1, const float4 v2, const float front_o,
                          const float faces, const float area)
{
    const float r1sq = dot(v1, v1), r2sq = dot(v2, v2);
    return fabs(v1.y) * front_o * area / (r1sq * r1sq) * fabs(v2.y) * faces / (r2sq * r2sq);
}

// Work-group sum of one float per work item (WG a power of two).
inline float group_sum(float x, __local float *scratch)
{
    const int lid = get_local_id(0);
    scratch[lid] = x;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int stride = WG / 2; stride > 0; stride /= 2) {
        if (lid < stride) scratch[lid] += scratch[lid + stride];
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    const float total = scratch[0];
    barrier(CLK_LOCAL_MEM_FENCE);
    return total;
}

// Cell c of `row` seen from spot s: the Gauss points' weight sum, the weighted mean of their
// path difference from the cell centre's path (m) and its weighted variance (m^2).
inline float4 cell_at_spot(const float8 row, const int c, const float4 laser,
                           const float4 spot)
{
    FRAME_OF(row);
    const float area = f_w * f_h / (float)CELLS / 4.0f;
    const float front_o = fmax(dot(f_normal, laser - f_x), 0.0f);
    const float faces = fmax(dot(f_normal, spot - f_x), 0.0f);
    const float4 centre = f_x + cell_offset(f_across, f_w, f_h, c);
    const float4 a1 = centre - laser, a2 = spot - centre;
    const float r1 = length(a1), r2 = length(a2);
    // the moments about the centre's path: the points lie within a few cm of it, so
    // E[d^2] - E[d]^2 loses nothing to cancellation in float32
    float wsum = 0.0f, wd = 0.0f, wdd = 0.0f;
    for (int q = 0; q < 4; ++q) {
        const float4 e = gauss_offset(f_eu, f_ev, q);
        const float4 v1 = a1 + e, v2 = a2 - e;
        const float w = point_weight(v1, v2, front_o, faces, area);
        const float d = leg_change(a1, r1, e, length(v1)) + leg_change(a2, r2, -e, length(v2));
        wsum += w;
        wd += w * d;
        wdd += w * d * d;
    }
    const float mean = wd / fmax(wsum, 1e-30f);
    // (a float4: Intel's CPU OpenCL 2024 vectorizer returned a float4's y and z wrong in all
    // lanes but the first)
    return (float4)(wsum, mean, fmax(wdd / fmax(wsum, 1e-30f) - mean * mean, 0.0f), 0.0f);
}

__kernel __attribute__((reqd_work_group_size(WG, 1, 1)))
void plate_stats(__global const float8 *rows,        // [R] statistics rows (first in the upload)
                 __global const float4 *stat_spots,  // [S]
                 __global const float4 *stat_lasers, // [S]: each statistics spot's laser spot
                 const int n_stat,
                 __global float *keep,               // [R][CELLS]
                 __global float *stats)              // [R][1 + S]: blur^2, shift at each spot
{
    __local float var_c[CELLS];
    __local float scratch[WG];
    const int r = get_group_id(0), lid = get_local_id(0);
    const float8 row = rows[r];
    // each cell's variance over the statistics spots, weighted by the weight it sends there
    float lit_var = 0.0f, lit_n = 0.0f;
    for (int c = lid; c < CELLS; c += WG) {
        float num = 0.0f, den = 0.0f;
        for (int s = 0; s < n_stat; ++s) {
            const float4 got = cell_at_spot(row, c, stat_lasers[s], stat_spots[s]);
            num += got.z * got.x;
            den += got.x;
        }
        var_c[c] = num / fmax(den, 1e-30f);
        if (den > 0.0f) {
            lit_var += var_c[c];
            lit_n += 1.0f;
        }
    }
    const float sum_var = group_sum(lit_var, scratch);  // (its barriers publish var_c)
    const float count = group_sum(lit_n, scratch);
    const float blur2 = BLUR_SHARE * sum_var / fmax(count, 1.0f);
    for (int c = lid; c < CELLS; c += WG)
        keep[r * CELLS + c] = sqrt(clamp(1.0f - blur2 / fmax(var_c[c], 1e-30f), 0.0f, 1.0f));
    barrier(CLK_GLOBAL_MEM_FENCE);
    // the shift at each statistics spot: one work item per spot, over every cell
    for (int s = lid; s < n_stat; s += WG) {
        float lost = 0.0f, wsum = 0.0f;
        for (int c = 0; c < CELLS; ++c) {
            const float4 got = cell_at_spot(row, c, stat_lasers[s], stat_spots[s]);
            const float k = keep[r * CELLS + c];
            lost += (1.0f - k * k) * got.y * got.x;
            wsum += got.x;
        }
        stats[r * (1 + n_stat) + 1 + s] = lost / fmax(wsum, 1e-30f);
    }
    if (lid == 0) stats[r * (1 + n_stat)] = blur2;
}

// erf-difference taps of the bin-integrated pulse (deposit.taps_of): a unit weight at the
// centre of phase p of the sub-bins i bins after bin k's window start puts into bin k
// erf((m + OS - 1/2) s) - erf((m - 1/2) s), m = (pad - i) OS - p, s = dsub / (sqrt 2 sigma).
inline float tap(const int p, const int i, const int pad, const float s)
{
    const float m = (float)((pad - i) * OS - p);
    return erf1((m + OS - 0.5f) * s) - erf1((m - 0.5f) * s);
}

__kernel __attribute__((reqd_work_group_size(WG, 1, 1)))
void plate_hist(__global const float *per_call,      // the host's one upload: [R] statistics
                                                     // rows, then these:
                const int rows_at,                   // [B] rows (float8 units)
                const int centre_at,                 // [B][D]: each centre's path - the
                                                     // window's first sub-bin's lower edge (m)
                const int stat_at,                   // [B]: the statistics row each plate uses
                __global const float *keep,          // [R][CELLS] (plate_stats)
                __global const float *stats,         // [R][1 + S]
                __global const float *affine,        // [D][S]: shift at spot d from the S spots'
                const int n_stat,
                __global const float4 *spots,        // [D]
                __global const float4 *lasers,       // [D]: each detector's laser spot
                __global const float *inv_dsub,      // [D]: sub-bins per metre of path
                const float sigma0sq,                // the pulse's sigma^2 less the box excess
                const int n_bins, const int pad,
                __global uint *dep,                  // [B][D][(n_bins + 2 pad) OS] scratch
                __global float *taps,                // [B][D][2 pad + 1][OS] scratch
                __global float *hist)                // [B][D][n_bins]
{
    __local float scratch[WG];
    __local float point_w[POINTS], point_u[POINTS];
    const int b = get_group_id(0), d = get_group_id(1), n_det = get_num_groups(1);
    const int lid = get_local_id(0);
    const int span = 2 * pad + 1, n_sub = (n_bins + 2 * pad) * OS;
    const int r = (int)per_call[stat_at + b];
    FRAME_OF(vload8(rows_at + b, per_call));
    const float4 laser3 = lasers[d], spot = spots[d];
    const float area = f_w * f_h / (float)CELLS / 4.0f;
    const float front_o = fmax(dot(f_normal, laser3 - f_x), 0.0f);
    const float faces = fmax(dot(f_normal, spot - f_x), 0.0f);
    const float4 a1 = f_x - laser3, a2 = spot - f_x;
    const float r1 = length(a1), r2 = length(a2);
    float shift = 0.0f;
    for (int s = 0; s < n_stat; ++s)
        shift += affine[d * n_stat + s] * stats[r * (1 + n_stat) + 1 + s];
    const float sigma = sqrt(sigma0sq + stats[r * (1 + n_stat)]);
    const float per_m = inv_dsub[d];
    const float start = per_call[centre_at + b * n_det + d] + shift;  // the centre's path in the window
    __global uint *mine = dep + (size_t)(b * n_det + d) * n_sub;
    __global float *my_taps = taps + (size_t)(b * n_det + d) * OS * span;
    for (int j = lid; j < n_sub; j += WG)
        mine[j] = 0u;
    const float s = 1.0f / (per_m * sqrt(2.0f) * sigma);
    for (int t = lid; t < OS * span; t += WG)  // [i][p]: a bin's phases side by side
        my_taps[t] = tap(t % OS, t / OS, pad, s);
    // each point's weight and sub-bin position, kept in local memory for the deposit; the
    // fixed-point scale maps the weights' sum to 2^30, so no sub-bin's sum can overflow
    float wsum = 0.0f;
    for (int m = lid; m < POINTS; m += WG) {
        const int q = m / CELLS, c = m % CELLS;
        const float4 e = cell_offset(f_across, f_w, f_h, c)
                         + keep[r * CELLS + c] * gauss_offset(f_eu, f_ev, q);
        const float4 v1 = a1 + e, v2 = a2 - e;
        const float w = point_weight(v1, v2, front_o, faces, area);
        const float rel = leg_change(a1, r1, e, length(v1)) + leg_change(a2, r2, -e, length(v2));
        point_w[m] = w;
        point_u[m] = (start + rel) * per_m - 0.5f;  // from sub-bin centres
        wsum += w;
    }
    const float total = group_sum(wsum, scratch);  // (its barriers publish the points too)
    barrier(CLK_GLOBAL_MEM_FENCE);  // the zeroed deposit and the taps
    // (no early return where the plate faces away, total 0: every work item must reach the
    // barrier below, and PoCL 3.1 miscompiled the kernel that had one; the deposit stays 0)
    const float scale = (total > 0.0f) ? 1073741824.0f / total : 0.0f;
    for (int m = lid; m < POINTS; m += WG) {
        const float w = point_w[m], u = point_u[m];
        if (!(w > 0.0f) || !(u >= 0.0f) || u >= (float)(n_sub - 1))  // (before the int cast:
            continue;                                                // out of range, undefined)
        const float fu = floor(u);
        const int j = (int)fu;
        const float t = u - fu;
        atomic_add(mine + j, convert_uint_rte(w * (1.0f - t) * scale));
        atomic_add(mine + j + 1, convert_uint_rte(w * t * scale));
    }
    barrier(CLK_GLOBAL_MEM_FENCE);
    const float unscale = total / 1073741824.0f;
    for (int k = lid; k < n_bins; k += WG) {
#if OS % 8 == 0  // eight phases at a time
        float8 acc = (float8)(0.0f);
        for (int i = 0; i < span; ++i)
            for (int p = 0; p < OS; p += 8)
                acc = fma(convert_float8(vload8(0, mine + (k + i) * OS + p)),
                          vload8(0, my_taps + i * OS + p), acc);
        const float sum = (acc.s0 + acc.s1) + (acc.s2 + acc.s3) + (acc.s4 + acc.s5)
                          + (acc.s6 + acc.s7);
#else
        float sum = 0.0f;
        for (int i = 0; i < span; ++i)
            for (int p = 0; p < OS; ++p)
                sum = fma((float)mine[(k + i) * OS + p], my_taps[i * OS + p], sum);
#endif
        hist[(size_t)(b * n_det + d) * n_bins + k] = sum * unscale;
    }
}
