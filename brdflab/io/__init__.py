"""Files: BRDFLab XML, meshes, and the data shipped with the package."""
