"""Analytic materials (lobes in Linear or Fixed combinations) and their albedo."""
