"""Simulated materials: BRDFs computed by a simulation (SCATMECH through pySCATMECH, or the
lab's own ray-bounce microgeometry simulator), tabulated once and then used as a source."""
