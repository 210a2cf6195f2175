"""``python -m shadowlab`` is the ``shadowlab`` command."""
from .cli import main

raise SystemExit(main())
