"""Geometry recovered from 3D Gaussians: a solid surface per object where the scene ships no mesh (InteriorGS)."""
