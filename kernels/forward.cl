// Forward model (paper Eq. 19-21): every facet adds a delayed, attenuated Gaussian pulse.
//
// Detectors are processed in groups (det0 = the group's first) when the path and weight rows
// of all detectors would not fit in one device allocation.
//
// The exact path, two kernels, both gather-style (a work item owns every value it writes: no
// atomics, deterministic sums):
//   facet_paths: per (chunk of CHUNK facets, detector) the hidden path s = r1 + r2 and the
//                geometric weight g = cos_a1 cos_b1 cos_a2 cos_b2 area / (r1^2 r2^2), plus the
//                [min, max] path of the chunk's contributing facets (for culling).
//   pulse_bins:  per (block of 15 bins, detector) the sum over facets of
//                g * (erf(z_hi) - erf(z_lo)),  z = (bin edge - s) / (sqrt(2) sigma),
//                i.e. twice the pulse energy fraction that falls inside each bin. The host
//                applies 0.5 * energy * f_c f_w^2 S_A S_d / (d^2 dt) in float64.
// Everything is in metres of hidden path; float32 throughout.
//
// The fast path (deposit, resolve, convolve): each facet's weight is split between the two
// sub-bins (OS per bin) around its path, linearly (its weight and its weighted path are kept
// exactly), then one correlation with the bin-integrated pulse per phase of the sub-bins
// gives every bin. The deposit is a scatter, made deterministic by summing in 64-bit fixed
// point with 32-bit integer atomics (core OpenCL 1.1): integer sums do not depend on the
// order of the additions, so the result is bit-identical run after run. deposit_rows adds the
// same integers without atomics, one work item per detector (many detectors on a CPU).
// deposit_direct fuses facet_paths and the deposit for short windows on many detectors of a
// CPU device, in float sums each work item owns (the same numbers run after run).
//
// Build options: -D CHUNK=<facets per chunk> [-D REFLECTANCE_FACTOR(n, to_laser, to_detector)=...]
// (with the GGX model also -D GGX_A2, GGX_KD, GGX_KS; with the retroreflective one -D
// RETRO_HALF_LAM, RETRO_KD, RETRO_KL) [-D PAIRED=0|1]. Occlusion
// (nlos_cl/visibility.py) comes as a per-(detector, facet) mask: a facet that does not see both
// spots sends nothing.
// PAIRED (facet_paths only): 0 (default), one laser spot O for every detector, passed as a
// float4 argument; 1, each detector its own, lasers[d] (confocal and paired layouts). Each work
// item computes its facets' laser legs either way: only where O comes from differs.

#include "common.h"

#ifndef PAIRED
#define PAIRED 0
#endif
#if PAIRED
#define LASER_ARG __global const float4 *lasers  // [n_det]: each detector's laser spot
#define LASER_OF(d) lasers[d].xyz
#else
#define LASER_ARG const float4 laser             // laser spot O, every detector's
#define LASER_OF(d) laser.xyz
#endif

// The target's direction-dependent reflectance (nlos_cl/reflectance.py); its constant part is
// applied on the host. Lambertian: 1.
#ifndef REFLECTANCE_FACTOR
#define REFLECTANCE_FACTOR(n, to_laser, to_detector) 1.0f
#endif

#ifdef GGX_A2
// GGX microfacet lobe over a diffuse base (nlos_cl.physics.reflectance.GGX): f / scale =
// KD + KS a^2 / ((n.h)^2 (a^2 - 1) + 1)^2 G1(l) G1(v) / (4 cos_l cos_v); called only where
// both cosines are positive.
inline float ggx_g1(const float c)
{
    return 2.0f / (1.0f + sqrt(1.0f + GGX_A2 * (1.0f - c * c) / (c * c)));
}

inline float ggx_factor(const float3 n, const float3 l, const float3 v)
{
    const float cl = dot(n, l), cv = dot(n, v);
    const float ch = dot(n, normalize(l + v));
    const float den = fma(ch * ch, GGX_A2 - 1.0f, 1.0f);
    return GGX_KD + GGX_KS * GGX_A2 / (den * den) * ggx_g1(cl) * ggx_g1(cv) / (4.0f * cl * cv);
}
#endif

#ifdef RETRO_HALF_LAM
// Retroreflective lobe over a diffuse base (nlos_cl.physics.reflectance.Retroreflective):
// f / scale = KD + KL exp(-(lam / 2) |l - v|^2), |l - v|^2 = 2 (1 - l.v) taken from the
// difference (no cancellation near the retro direction); called only where both cosines are
// positive.
inline float retro_factor(const float3 l, const float3 v)
{
    const float3 gap = l - v;
    return RETRO_KD + RETRO_KL * exp(-RETRO_HALF_LAM * dot(gap, gap));
}
#endif

__kernel void facet_paths(__global const float4 *centres,  // xyz of each facet
                          __global const float4 *normals,  // unit normal xyz, w = area (m^2)
                          const int n_facets,
                          __global const float4 *spots,    // detector spots on the wall
                          LASER_ARG,                       // laser spot(s): see PAIRED
                          const int det0,                  // first detector of this group
                          __global const uchar *visible,   // [n_det][n_facets] if has_visible
                          const int has_visible,           // 0: every facet sees both spots
                          __global float *path,            // [group][n_chunks * CHUNK]
                          __global float *weight,          // [group][n_chunks * CHUNK]
                          __global float4 *chunk_range)    // [group][n_chunks]: min, max path, weight sum
{
    const int chunk = get_global_id(0);
    const int det = get_global_id(1);  // within the group
    const int n_chunks = get_global_size(0);
    const int row = det * n_chunks * CHUNK;
    const float3 spot = spots[det0 + det].xyz;
    const float3 o = LASER_OF(det0 + det);
    float lo = INFINITY, hi = -INFINITY, total = 0.0f;
    for (int k = 0; k < CHUNK; ++k) {
        const int f = chunk * CHUNK + k;
        float s = 0.0f, g = 0.0f;
        if (f < n_facets) {
            const float3 c = centres[f].xyz;
            const float4 nw = normals[f];
            const float3 v1 = c - o;      // O -> facet
            const float3 v2 = spot - c;   // facet -> detector spot
            const float r1 = length(v1), r2 = length(v2);
            s = r1 + r2;
            // Facets facing away from O or from the detector spot receive / send nothing.
            const float cos_b1 = -dot(nw.xyz, v1) / r1;
            const float cos_a2 = dot(nw.xyz, v2) / r2;
            const float cos_a1 = fabs(v1.y) / r1;  // the wall's normal is +y
            const float cos_b2 = fabs(v2.y) / r2;
            const int seen = !has_visible || visible[(det0 + det) * n_facets + f];
            if (cos_b1 > 0.0f && cos_a2 > 0.0f && seen) {
                g = cos_a1 * cos_b1 * cos_a2 * cos_b2 * nw.w / (r1 * r1 * r2 * r2)
                    * REFLECTANCE_FACTOR(nw.xyz, -v1 / r1, v2 / r2);
                lo = fmin(lo, s);
                hi = fmax(hi, s);
                total += g;
            }
        }
        path[row + f] = s;
        weight[row + f] = g;
    }
    chunk_range[det * n_chunks + chunk] = (float4)(lo, hi, total, 0.0f);
}

// 15 bins have 16 edges: one float16 erf per facet serves the whole block (measured on PoCL:
// 1.8x faster than 8 bins from a float8 erf plus a scalar one for the last edge).
#define BLOCK 15

__kernel void pulse_bins(__global const float *path,
                         __global const float *weight,
                         __global const float4 *chunk_range,
                         const int n_chunks,
                         __global const float2 *edges,   // per detector: (path at bin-0 start, path per bin)
                         const float inv_sqrt2_sigma,    // 1 / (sqrt(2) sigma_path)
                         const float reach,              // facets farther than this from a bin are culled
                         const int n_bins,
                         const int det0,                 // first detector of this group
                         __global float *hist)           // [n_det][n_bins]
{
    const int block = get_global_id(0);
    const int det = get_global_id(1);  // within the group: path, weight, chunk_range rows
    const int k0 = block * BLOCK;
    if (k0 >= n_bins) return;
    const float2 ax = edges[det0 + det];
    // The block's first edge, then offsets below it: every bin's two edges come from the same
    // base, so each bin width is exact to ~1e-9 m even though paths are ~10 m in float32.
    const float base = ax.x + ax.y * (float)k0;
    const float16 offs = ax.y * (float16)(0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f,
                                          8.0f, 9.0f, 10.0f, 11.0f, 12.0f, 13.0f, 14.0f, 15.0f);
    const float win_lo = base - reach, win_hi = base + ax.y * BLOCK + reach;
    const int row = det * n_chunks * CHUNK;
    float16 acc = (float16)(0.0f);  // lane 15 is unused
    for (int c = 0; c < n_chunks; ++c) {
        const float4 r = chunk_range[det * n_chunks + c];
        if (r.y < win_lo || r.x > win_hi) continue;  // the whole chunk is out of reach
        for (int k = 0; k < CHUNK; ++k) {
            const int f = row + c * CHUNK + k;
            const float s = path[f];
            const float g = weight[f];
            if (g == 0.0f || s < win_lo || s > win_hi) continue;
            const float d = base - s;  // exact (Sterbenz): base and s are within `reach`
            const float16 e = erf16((d + offs) * inv_sqrt2_sigma);  // the block's 16 edges
            acc += g * ((float16)(e.s1234, e.s5678, e.s9abc, e.sdef, e.sf) - e);
        }
    }
    float bins[16];
    vstore16(acc, 0, bins);
    __global float *out = hist + (det0 + det) * n_bins + k0;
    for (int j = 0; j < BLOCK && k0 + j < n_bins; ++j) out[j] = bins[j];
}

// ------------------------------------------------------------------ deposit and convolve
// Build options (besides CHUNK): -D OS=<sub-bins per bin> -D SPAN=<taps per phase>.
// Per detector the deposit covers a window of bins; dep holds [group][OS phases][padded]
// sub-bins, phase-major: sub-bin j (from the window's base) is dep[j % OS][j / OS].
#ifndef OS
#define OS 1
#endif
#ifndef SPAN
#define SPAN 1
#endif

// A facet's weight g at hidden path `p`, split linearly between the two sub-bins around it:
// share `side` (0 the lower, 1 the upper) as a 64-bit fixed-point number, and where it goes in
// the detector's [OS][padded] sub-bins (-1: off the time axis by more than the reach). Both
// deposits below take their numbers from here, so their sums are the same integers.
inline int split_share(const float g, const float p, const float4 w, const int padded,
                       const int side, ulong *q)
{
    const float u = (p - w.x) * w.y - 0.5f;  // from sub-bin centres
    const float fu = floor(u);
    const float t = u - fu;
    const int k = (int)fu + side;
    if (k < 0 || k / OS >= padded) return -1;
    *q = convert_ulong_rte(g * (side ? t : 1.0f - t) * w.z);
    return (k % OS) * padded + k / OS;
}

__kernel void deposit(__global const float *path, __global const float *weight,
                      const int n_pad,
                      __global const float4 *win,      // per detector: base path, 1 / dsub, fixed-point scale
                      const int padded, const int det0,
                      __global uint *lo, __global uint *hi)  // [group][OS][padded] 64-bit sums
{
    const int f = get_global_id(0), det = get_global_id(1);
    const float g = weight[det * n_pad + f];
    if (g == 0.0f) return;
    const float4 w = win[det0 + det];
    for (int side = 0; side < 2; ++side) {
        ulong q;
        const int k = split_share(g, path[det * n_pad + f], w, padded, side, &q);
        if (k < 0) continue;
        const int at = det * OS * padded + k;
        const uint low = (uint)q;
        const uint old = atomic_add(lo + at, low);
        const uint carry = (old + low < old) ? 1u : 0u;
        atomic_add(hi + at, (uint)(q >> 32) + carry);
    }
}

// deposit_rows: the same sums, one work item per detector over all of its facets in order: it
// owns that detector's sub-bins, so each 64-bit fixed-point sum is a plain read, add and write,
// and integer addition makes the result the atomic kernel's, bit for bit. For many detectors
// on CPU devices, whose atomics cost more than the arithmetic (nlos_cl/ops/forward_passes.py
// `deposit_kernel`).
__kernel void deposit_rows(__global const float *path, __global const float *weight,
                           const int n_pad,
                           __global const float4 *win,
                           const int padded, const int det0,
                           __global uint *lo, __global uint *hi)
{
    const int det = get_global_id(0);
    const float4 w = win[det0 + det];
    __global const float *p = path + det * n_pad, *gw = weight + det * n_pad;
    __global uint *row_lo = lo + det * OS * padded, *row_hi = hi + det * OS * padded;
    for (int f = 0; f < n_pad; ++f) {
        const float g = gw[f];
        if (g == 0.0f) continue;
        for (int side = 0; side < 2; ++side) {
            ulong q;
            const int at = split_share(g, p[f], w, padded, side, &q);
            if (at < 0) continue;
            const ulong sum = ((((ulong)row_hi[at]) << 32) | (ulong)row_lo[at]) + q;
            row_lo[at] = (uint)sum;
            row_hi[at] = (uint)(sum >> 32);
        }
    }
}

__kernel void resolve(__global const uint *lo, __global const uint *hi,
                      __global const float4 *win, const int padded, const int det0,
                      __global float *dep)  // [group][OS][padded]
{
    const int i = get_global_id(0), det = get_global_id(1);
    const int at = det * OS * padded + i;
    dep[at] = fma((float)hi[at], 4294967296.0f, (float)lo[at]) / win[det0 + det].z;
}

// out[k] = sum over phases p and taps t of dep[p][k - first + t] * taps[p][t] for k in the
// detector's window [first, first + count), 0 elsewhere; 16 bins per work item.
__kernel void convolve(__global const float *dep, __constant const float *taps,  // [OS][SPAN]
                       __global const int2 *window,  // per detector of the group: first bin, bin count
                       const int padded, const int n_bins, const int det0,
                       __global float *hist)         // [n_det][n_bins]
{
    const int k0 = get_global_id(0) * 16, det = get_global_id(1);
    const int2 wnd = window[det];  // the group's own rows
    float16 acc = (float16)(0.0f);
    const int i0 = k0 - wnd.x;
    if (i0 >= 0 && i0 < wnd.y) {  // windows start on a multiple of 16 bins
        for (int p = 0; p < OS; ++p) {
            __global const float *src = dep + (det * OS + p) * padded + i0;
            for (int t = 0; t < SPAN; ++t)
                acc = fma(vload16(0, src + t), (float16)(taps[p * SPAN + t]), acc);
        }
    }
    float bins[16];
    vstore16(acc, 0, bins);
    __global float *out = hist + (det0 + det) * n_bins + k0;
    for (int j = 0; j < 16 && k0 + j < n_bins; ++j) {
        const int i = i0 + j;
        out[j] = (i >= 0 && i < wnd.y) ? bins[j] : 0.0f;
    }
}

// deposit_direct: facet_paths and deposit_rows in one pass, for short windows on many
// detectors on a CPU device (a model fit's columns: ~100 bins a detector; ops/forward_passes.py
// `direct`). One work item per detector walks the facets 16 at a time (float16 lanes: PoCL
// does not vectorize the per-detector loop across work items) from structure-of-arrays rows,
// computes each path and weight as facet_paths does (the four cosines and 1 / (r1^2 r2^2) as
// one quotient) and adds the linear split straight into the detector's float sub-bins: it owns
// them, so the additions keep one order and the sums are the same run after run. No path or
// weight rows are written and read back, and no fixed point is needed. The window is the whole
// axis: win.x is T bins before bin 0 (convolve's window (0, n_bins)). Lambertian targets
// without an occlusion mask only (the others take facet_paths).
// span: each detector's min and max contributing path (facet_paths' chunk ranges reduced).
__kernel void deposit_direct(__global const float *facets,  // [7][n16]: cx cy cz nx ny nz area
                             const int n16,                  // facets padded to 16 (area 0)
                             __global const float4 *spots, LASER_ARG, const int det0,
                             __global const float4 *win,     // per detector: base path, 1 / dsub
                             const int padded,
                             __global float *dep,            // [group][OS][padded], zeroed
                             __global float2 *span)          // [group]
{
    const int det = get_global_id(0);  // within the group
    const float3 spot = spots[det0 + det].xyz;
    const float3 o = LASER_OF(det0 + det);
    const float4 w = win[det0 + det];
    const float last = (float)(OS * padded);  // sub-bin indices clamped to [-2, last]
    __global float *row = dep + det * OS * padded;
    float16 lo16 = (float16)(INFINITY), hi16 = (float16)(-INFINITY);
    for (int f = 0; f < n16; f += 16) {
        const float16 cx = vload16(0, facets + f), cy = vload16(0, facets + n16 + f),
                      cz = vload16(0, facets + 2 * n16 + f);
        const float16 nx = vload16(0, facets + 3 * n16 + f),
                      ny = vload16(0, facets + 4 * n16 + f),
                      nz = vload16(0, facets + 5 * n16 + f),
                      area = vload16(0, facets + 6 * n16 + f);
        const float16 ax = cx - o.x, ay = cy - o.y, az = cz - o.z;           // O -> facet
        const float16 bx = spot.x - cx, by = spot.y - cy, bz = spot.z - cz;  // facet -> spot
        const float16 r1sq = ax * ax + ay * ay + az * az, r2sq = bx * bx + by * by + bz * bz;
        const float16 s = sqrt(r1sq) + sqrt(r2sq);
        const float16 nb1 = -(nx * ax + ny * ay + nz * az);  // r1 cos_b1
        const float16 na2 = nx * bx + ny * by + nz * bz;     // r2 cos_a2
        const int16 lit = (nb1 > 0.0f) & (na2 > 0.0f);       // faces O and the spot
        // cos_a1 cos_b1 cos_a2 cos_b2 area / (r1^2 r2^2); the wall's normal is +y
        const float16 g = fabs(ay) * nb1 * na2 * fabs(by) * area / (r1sq * r1sq * r2sq * r2sq);
        lo16 = select(lo16, fmin(lo16, s), lit);
        hi16 = select(hi16, fmax(hi16, s), lit);
        const float16 u = (s - w.x) * w.y - 0.5f;  // from sub-bin centres
        const float16 fu = clamp(floor(u), -2.0f, last);
        float gs[16], ts[16];
        int ks[16];
        vstore16(select((float16)(0.0f), g, lit), 0, gs);
        vstore16(u - floor(u), 0, ts);
        vstore16(convert_int16(fu), 0, ks);
        for (int j = 0; j < 16; ++j) {
            if (gs[j] == 0.0f) continue;
            const int k = ks[j];
            if (k >= 0 && k / OS < padded)
                row[(k % OS) * padded + k / OS] += gs[j] * (1.0f - ts[j]);
            if (k + 1 >= 0 && (k + 1) / OS < padded)
                row[((k + 1) % OS) * padded + (k + 1) / OS] += gs[j] * ts[j];
        }
    }
    float l[16], h[16];
    vstore16(lo16, 0, l);
    vstore16(hi16, 0, h);
    float lo = INFINITY, hi = -INFINITY;
    for (int j = 0; j < 16; ++j) {
        lo = fmin(lo, l[j]);
        hi = fmax(hi, h[j]);
    }
    span[det] = (float2)(lo, hi);
}
