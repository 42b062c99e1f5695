"""Gymnasium adapters over agvsim and localizer (see issue: Gymnasium environments)."""
