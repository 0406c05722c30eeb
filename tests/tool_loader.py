"""Import a script from tools/ (not a package) as a module, for the tests of the tools:
``load_tool("studies/mo_benchmark")`` loads tools/studies/mo_benchmark.py."""

import importlib.util
import os
import sys


def load_tool(path: str):
    name = os.path.basename(path)
    file = os.path.join(os.path.dirname(__file__), "..", "tools", f"{path}.py")
    if not os.path.isfile(file):
        raise FileNotFoundError(f"no tool at tools/{path}.py; give its folder too, e.g. load_tool('studies/{name}')")
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module
