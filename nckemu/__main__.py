import sys

from nckemu.cli import main

sys.exit(main())
