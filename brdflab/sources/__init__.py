"""Everything a BRDF can come from besides lobes: measured files, and opening any file."""
