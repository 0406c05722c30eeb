"""Preference-conditioned rsl-rl models."""

from pchc_rsl.modules.pci import GatedMoEActor, PCIActor, PreferenceMLPModel

__all__ = ["GatedMoEActor", "PCIActor", "PreferenceMLPModel"]
