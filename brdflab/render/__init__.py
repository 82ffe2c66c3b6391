"""The render layer: moderngl programs assembled from the model registry.

Everything here draws into any moderngl context: a QOpenGLWidget's or a standalone
EGL one (`create_context`).
"""
