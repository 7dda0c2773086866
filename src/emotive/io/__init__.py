"""Motion file formats: BVH reading and writing."""
