"""Export a material or stored fit in formats other tools read."""
