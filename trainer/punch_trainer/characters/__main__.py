"""`python -m punch_trainer.characters`: writes the CC0 test characters (see punch_trainer.characters.build)."""

import sys

from punch_trainer.characters.build import main

sys.exit(main())
