import sys

from fieldbox.cli import main

sys.exit(main())
