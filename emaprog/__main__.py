"""``python -m emaprog``: the same command line as the ``emaprog`` script."""

from .cli import app

if __name__ == "__main__":  # spawned sweep workers import this module: run nothing then
    app(prog_name="emaprog")
