"""pchc_rsl: preference-conditioned humanoid control (PCHC) as an extension of rsl-rl.

The core (this package's modules, algorithms, storage, runners, export, utils, preference and pareto) needs only
torch, tensordict and rsl-rl, never mujoco, so other rsl-rl projects can use the PCI actor and MultiCriticPPO. The
layout: docs/design.md.
"""

__version__ = "0.1.0"
