"""Layer 2: the hidden scene on the host: setups, targets, meshes, reflectance, occlusion,
wall-spot layouts, trajectories and noise models. No device code."""
