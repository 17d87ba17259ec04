"""Reproductions of the papers' studies, kept apart from the library core: the 2006 paper's
Table 1 comparison and the 2014 paper's initial-alignment study (simulated and real data)."""

__all__: list[str] = []
