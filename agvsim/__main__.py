import sys

from agvsim.cli import main

sys.exit(main())
