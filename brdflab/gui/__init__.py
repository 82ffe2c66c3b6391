"""The Qt desktop application: a thin layer over the core and the renderers."""
