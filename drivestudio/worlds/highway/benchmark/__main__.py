"""`python -m drivestudio.worlds.highway.benchmark worker`: a worker process of `drivestudio benchmark`."""
import sys

from drivestudio.worlds.highway.benchmark.run import worker_main

if sys.argv[1:] == ["worker"]:
    sys.exit(worker_main())
sys.exit("usage: python -m drivestudio.worlds.highway.benchmark worker (started by `drivestudio benchmark`)")
