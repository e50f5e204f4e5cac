"""3D Gaussians: the scene's appearance (PLY I/O, mesh sampling, instance ids, pruning)."""
