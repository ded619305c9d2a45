"""Command line (filled in by the pipeline work)."""


def main(argv: list[str] | None = None) -> int:
    return 0
