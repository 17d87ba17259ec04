"""Presentation: plots, HTML reports and the replay report's table, JSON and figure."""

__all__: list[str] = []
