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

// Final stage, fused with the neighbourhood read: 9 work items each pick the first maximum
// among the first stage's candidates (in work-item order: the lowest flat index wins ties),
// and item w copies row (dz, dy) = (w / 3 - 1, w % 3 - 1) of the 3 x 3 x 3 cells around it
// from the map (NaN outside the grid). result: [ix, iy, iz, score, 0, 0, 0, 0, 27 scores];
// ix = -1 when no cell beat -INFINITY. One small read then gives the estimator all it needs.
__kernel void argmax_patch(__global const float *best_value, __global const int *best_index,
                           const int items, __global const float *score,
                           const int nx, const int ny, const int nz,
                           __global float *result)
{
    const int w = get_global_id(0);
    float best = -INFINITY;
    int where = -1;
    for (int j = 0; j < items; ++j) {
        if (best_value[j] > best) { best = best_value[j]; where = best_index[j]; }
    }
    const int ix = where < 0 ? -1 : where % nx;
    const int iy = where < 0 ? 0 : (where / nx) % ny, iz = where < 0 ? 0 : where / (nx * ny);
    if (w == 0) {
        result[0] = (float)ix; result[1] = (float)iy; result[2] = (float)iz; result[3] = best;
        result[4] = result[5] = result[6] = result[7] = 0.0f;
    }
    const int ry = iy + w % 3 - 1, rz = iz + w / 3 - 1;
    const int row_inside = where >= 0 && ry >= 0 && ry < ny && rz >= 0 && rz < nz;
    for (int j = 0; j < 3; ++j) {
        const int cx = ix - 1 + j;
        const int inside = row_inside && cx >= 0 && cx < nx;
        result[8 + 3 * w + j] = inside ? score[(rz * ny + ry) * nx + cx] : NAN;
    }
}
