"""Offline, once (Sung 2011, sections 3-4): limb IK, speed maps, the motion graph, libraries from
BVH manifests, the library artifact."""
