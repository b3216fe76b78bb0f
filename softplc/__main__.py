import sys

from softplc.cli import main

sys.exit(main())
