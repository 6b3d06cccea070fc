import sys

from softhand_env.figures import main

sys.exit(main())
