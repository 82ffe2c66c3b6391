"""The render layer: moderngl programs assembled from the model registry.

Everything here draws into any moderngl context: the standalone ones of
`create_context` (EGL first), which the command line and the window's views both use.
"""
