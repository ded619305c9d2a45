"""Posting: CL data in, a verified NC program out."""
