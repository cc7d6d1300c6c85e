"""`python -m fraytool` runs the command line."""
from fraytool.cli import main

raise SystemExit(main())
