"""Motion data: quaternions, skeletons and FK, clips, BVH, foot contacts."""
