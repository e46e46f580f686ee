from plate_env.cli import main

raise SystemExit(main())
