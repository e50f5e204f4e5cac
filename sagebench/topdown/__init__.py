"""Semantic top-down map: surface-sampled footprints, rasters, height-band occupancy, reachability, picture."""
