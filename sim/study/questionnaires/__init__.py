"""The study's standard questionnaires and the lab's own single items: the instruments as data (ssq.json and
ipq.json beside this file, each citing its source), read and checked by instruments.py; their scoring by the
published keys (scoring.py); the answers and scores as tidy rows (rows.py). Pure logic, but for reading those files
and writing the rows. When each is asked in a session is the design's (design.yaml) and the plan's."""

from __future__ import annotations

__all__: list[str] = []
