// Background removal for a stream of frames (Gariepy et al. 2016): out = frame - background,
// negatives clipped to 0 when CLIP is set; then, with alpha > 0, the background follows the
// frames as an exponential running mean, background += alpha (frame - background), in place
// (alpha = 0: a fixed, target-free reference). A work item owns one bin of both buffers.
//
// Build options: -D CLIP=0|1

__kernel void subtract_background(__global const float *frame,
                                  __global float *background,  // updated in place if alpha > 0
                                  const float alpha,
                                  const int n,
                                  __global float *out)
{
    const int i = get_global_id(0);
    if (i >= n) return;
    const float f = frame[i], b = background[i];
    const float d = f - b;
    out[i] = CLIP ? fmax(d, 0.0f) : d;
    if (alpha > 0.0f) background[i] = fma(alpha, d, b);
}
