"""One typed, serialisable config object per run.

A :class:`RunConfig` is a tree of dataclasses. Its flat form uses dotted keys
(``"surrogate.epochs"``), which map 1:1 onto ``tune.grid_search`` axes and ``--set`` overrides.

The run's domain has a section named after it (``maze.episodes``), a dataclass the domain's
registration supplies (:mod:`dsage_ray.domains.registry`), as are the domain's presets and
variants; this package knows no domain by name.

Resolution order when building a config: dataclass defaults → the domain's *preset* → the
*variant* → explicit keys. ``preset`` and ``variant`` are ordinary fields, so a Tune grid over
``variant`` is an ablation grid.

One module per job: :mod:`~dsage_ray.config.schema` (the sections and their keys),
:mod:`~dsage_ray.config.layering` (presets and variants), :mod:`~dsage_ray.config.validation` (the rules),
:mod:`~dsage_ray.config.migration` (old key names the records use), :mod:`~dsage_ray.config.parsing` (values, files,
``--set``) and :mod:`~dsage_ray.config.run` (:class:`RunConfig`, built from them).
"""

from dsage_ray.config.layering import COMMON_VARIANTS, paper_comparison, presets, variants
from dsage_ray.config.migration import REMOVED_KEYS, RENAMED_KEYS, RemovedKey, upgrade_keys
from dsage_ray.config.parsing import flatten, key_hint, parse_override, read_config_file, shown_value
from dsage_ray.config.run import RunConfig, changed_keys, resumed_config
from dsage_ray.config.schema import (ConfigError, EmitterName, ExperimentalConfig, MutatingEmitter, Precision,
                                     QDConfig, RayConfig, SearchMode, SelectionConfig, SelectionMethod,
                                     SurrogateConfig, SurrogateKind, key)

__all__ = ["COMMON_VARIANTS", "REMOVED_KEYS", "RENAMED_KEYS", "ConfigError", "EmitterName", "ExperimentalConfig",
           "MutatingEmitter", "Precision", "QDConfig", "RayConfig", "RemovedKey", "RunConfig", "SearchMode",
           "SelectionConfig", "SelectionMethod", "SurrogateConfig", "SurrogateKind", "changed_keys", "flatten",
           "key", "key_hint", "paper_comparison", "parse_override", "presets", "read_config_file",
           "resumed_config", "shown_value", "upgrade_keys", "variants"]
