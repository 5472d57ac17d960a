"""Ray set-up for the RLlib tests (run by ``.ci/rllib`` in a venv with the ``rllib`` extra).

Set before Ray is imported (Ray reads them at import): a Ray "cluster" of this machine alone, on the
loopback address (on Linux Ray otherwise advertises the host's network address even for a local
instance), and no usage statistics sent anywhere. The tests start their own local instance in a
temporary folder and stop it, and every process it started, before they end.
"""

import os

os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"  # node address = 127.0.0.1
os.environ["RAY_USAGE_STATS_ENABLED"] = "0"
