"""Import a script from tools/ (not a package) as a module, for the tests of the benchmark and release tools."""

import importlib.util
import os
import sys


def load_tool(name: str):
    path = os.path.join(os.path.dirname(__file__), "..", "tools", f"{name}.py")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module
