"""The Mario domain: GAN levels played by Robin Baumgarten's A* agent in the Mario AI framework.

Modules: :mod:`.tiles` (vocabulary, validation), :mod:`.human_levels` (training data),
:mod:`.generator` (DCGAN), :mod:`.encoding` (one-hot), :mod:`.simulator` (JPype game loop,
deterministic A* timer), :mod:`.evaluate` (objective, measures, occupancy), :mod:`.render`,
:mod:`.domain` (:class:`~dsage_ray.domains.mario.domain.MarioDomain`), :mod:`.cli`.
Nothing here imports torch or starts Java at package import time.
"""
