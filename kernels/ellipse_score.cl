// Ellipse scoring (paper Section 2.1 and 3.2): a grid cell c lies on detector i's ellipse of
// hidden path p_i = |c - O| + |c - spot_i|; its likelihood under detector i is the filtered
// signal at that path (linear interpolation between bin centres, 0 outside the record,
// negatives clipped to 0), normalised by the row maximum so products stay in float32 range.
// The joint likelihood is the product over detectors, or (LOG_MODE) the sum of
// log(max(v, LOG_FLOOR)), which stays finite for many detectors.
//
// Build options: -D N_DET=<detectors> -D LOG_MODE=0|1 -D LOG_FLOOR=<float>

__kernel void ellipse_score(__global const float *signal,   // [N_DET][n_bins]
                            __global const float2 *stats,   // [N_DET] (row max, mean square)
                            __global const float4 *spots,   // [N_DET] detector spots
                            const float4 laser,
                            __global const float2 *axis,    // [N_DET] (path at bin-0 centre, 1 / path per bin)
                            const int n_bins,
                            const float4 origin, const float4 step,
                            const int nx, const int ny,
                            __global float *score)          // [nz][ny][nx]
{
    const int ix = get_global_id(0), iy = get_global_id(1), iz = get_global_id(2);
    if (ix >= nx) return;
    const float3 c = origin.xyz + step.xyz * (float3)((float)ix, (float)iy, (float)iz);
    const float r1 = distance(c, laser.xyz);
#if LOG_MODE
    float joint = 0.0f;
#else
    float joint = 1.0f;
#endif
    for (int d = 0; d < N_DET; ++d) {
        const float2 ax = axis[d];
        const float u = (r1 + distance(c, spots[d].xyz) - ax.x) * ax.y;  // fractional bin
        const float fu = floor(u);
        const float t = u - fu;
        const int i0 = (int)fu;
        const int c0 = clamp(i0, 0, n_bins - 1), c1 = clamp(i0 + 1, 0, n_bins - 1);
        __global const float *row = signal + d * n_bins;
        const float v0 = (c0 == i0) ? row[c0] : 0.0f;
        const float v1 = (c1 == i0 + 1) ? row[c1] : 0.0f;
        const float peak = stats[d].x;
        const float v = (peak > 0.0f) ? fmax(mix(v0, v1, t), 0.0f) / peak : 0.0f;
#if LOG_MODE
        joint += log(fmax(v, LOG_FLOOR));
#else
        joint *= v;
#endif
    }
    score[(iz * ny + iy) * nx + ix] = joint;
}
