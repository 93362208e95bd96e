from roadx_ti.cli import main

raise SystemExit(main())
