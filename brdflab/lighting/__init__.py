"""Environment maps, spherical harmonics, sample sets and the reference view."""
