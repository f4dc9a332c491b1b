"""``python -m usdmotion`` = the ``usdmotion`` command."""

from usdmotion.cli import run

if __name__ == "__main__":
    run()
