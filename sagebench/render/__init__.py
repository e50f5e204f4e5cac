"""Seeing a scene: the Gaussians data model, pinhole cameras and the splat renderers (fast and reference)."""
