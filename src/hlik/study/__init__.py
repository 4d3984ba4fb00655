"""The paper's study (Sec. IV-A/B/C, V-A/B): retarget every take with every approach on every robot,
correlate the 11 criteria, derive the hierarchical weights and x0, and rank the approaches.

``approaches`` (what to run) -> ``dataset`` (one Parquet file of per-frame costs per cell) ->
``analysis`` (Spearman, Ward, weights, x0, rankings) -> ``report`` (figures, HTML); ``runner`` ties
them together, in-process or on Ray.
"""
