"""Shared code: Piccolo link and planning-protocol codecs, geodesy, assignment, simulator."""
