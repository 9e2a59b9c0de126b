"""``python -m twinsense``: the same command line as the ``twinsense`` script."""

from twinsense.cli import main

if __name__ == "__main__":
    main()
