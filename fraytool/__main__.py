"""`python -m fraytool` runs the command line."""
from fraytool.commands.main import main

raise SystemExit(main())
