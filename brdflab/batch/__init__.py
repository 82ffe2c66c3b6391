"""Batch fitting of whole databases: every (source, lobe set) pair is one task run by
Dask workers, with a resumable results table, one XML of fits per source, and charts."""
