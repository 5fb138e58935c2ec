"""`python -m drivestudio.benchmark worker`: a worker process of `drivestudio benchmark`."""
import sys

from .run import worker_main

if sys.argv[1:] == ["worker"]:
    sys.exit(worker_main())
sys.exit("usage: python -m drivestudio.benchmark worker (started by `drivestudio benchmark`)")
