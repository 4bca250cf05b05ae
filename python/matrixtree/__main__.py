from matrixtree.cli import main

raise SystemExit(main())
