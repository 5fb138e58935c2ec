from drivestudio.cli import main

raise SystemExit(main())
