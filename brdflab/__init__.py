"""brdflab: a laboratory for reflectance — design, measure, fit and render BRDFs.

The core (this package minus `render` and `gui`) imports neither Qt nor OpenGL.
"""

__version__ = "0.1.0"
