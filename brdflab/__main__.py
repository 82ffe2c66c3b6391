import sys

from brdflab.cli import main

sys.exit(main())
