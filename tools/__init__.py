"""Developer tools (code generators), run from the repository root as `python3 -m tools.<name>`."""
