// First stage of argmax: work item w scans cells [w * per_item, (w + 1) * per_item) and keeps
// the first maximum (strict >), so ties resolve to the lowest index on every device.
__kernel void argmax_partial(__global const float *score, const int n_cells, const int per_item,
                             __global float *best_value, __global int *best_index)
{
    const int w = get_global_id(0);
    const int start = w * per_item;
    const int stop = min(start + per_item, n_cells);
    float best = -INFINITY;
    int where = -1;
    for (int i = start; i < stop; ++i) {
        const float v = score[i];
        if (v > best) { best = v; where = i; }
    }
    best_value[w] = best;
    best_index[w] = where;
}
