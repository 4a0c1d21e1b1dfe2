"""Perceptual studies, from plan to analysis.

- :mod:`prosody.study.designs`: plans (paired comparison, MOS, identification) and their counterbalancing;
- :mod:`prosody.study.stimuli`: the videos (and 3D-head frames) of every condition of a plan;
- :mod:`prosody.study.store` and :mod:`prosody.study.server`: the ballot page and its answers' database;
- :mod:`prosody.study.ballots` (paired comparisons) and :mod:`prosody.study.ratings` (MOS, identification):
  reading and analysing the ballots.
"""
