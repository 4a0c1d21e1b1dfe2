"""``python -m prosody``: the same as the ``prosody`` command."""

import sys

from .cli import main

sys.exit(main())
