"""``python -m radtr_addon``: batch solves and benchmarks (see ``cli``)."""
import sys

from .cli import main

sys.exit(main())
