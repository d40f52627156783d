import sys

from lhd_loading_ros.cli.main import main

sys.exit(main())
