"""The native thread pools a capture process limits are found once, in the parent.

Finding them walks every loaded library; ``simulate._thread_pools`` keeps threadpoolctl's controller
until a module is loaded (which may bring a library), so each capture process limits the pools found
before the fork. That the limits reach the children's BLAS is tested in test_simulate_processes.
"""

import importlib
import sys

from threadpoolctl import ThreadpoolController

from twinsense.simulate import _thread_pools


def test_the_controller_is_kept_until_a_module_is_loaded():
    first = _thread_pools()
    assert isinstance(first, ThreadpoolController)
    assert _thread_pools() is first
    name = next(m for m in ("colorsys", "quopri", "wave", "netrc", "sndhdr") if m not in sys.modules)
    importlib.import_module(name)
    again = _thread_pools()
    assert again is not first and _thread_pools() is again
    # The same libraries' pools (the module loaded brings none).
    assert sorted(p.filepath for p in again.lib_controllers) == sorted(p.filepath for p in first.lib_controllers)
