"""``python -m app [PROJECT]``: open the studio (the same as ``facestudio studio [PROJECT]``)."""

import sys

from app.cli import main

if __name__ == "__main__":
    sys.exit(main(["studio", *sys.argv[1:]]))
