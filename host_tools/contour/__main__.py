from contour.cli import main

raise SystemExit(main())
