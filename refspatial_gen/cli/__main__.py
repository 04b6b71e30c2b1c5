"""`python -m refspatial_gen.cli ...` runs the same command line as `refspatial-gen`."""

import sys

from refspatial_gen.cli import main

sys.exit(main())
