"""The study's analysis over every participant's records: summaries and paired comparisons, the mixed models, the
equivalence tests against each test's SESOI, and the report with its plots."""

from __future__ import annotations

__all__: list[str] = []
