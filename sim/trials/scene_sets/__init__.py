"""Scene sets beside the demonstrations: what a collection shares, and scenes never picked.

:mod:`~sim.trials.scene_sets.samples` holds what every ``yumi`` collection makes of its images
(the samples, the questions a scene is asked); :mod:`~sim.trials.scene_sets.catalog_labels`
makes scenes labelled by the catalog's grasps without a physics pick, hundreds a minute;
:mod:`~sim.trials.scene_sets.randomised_looks` draws their looks wider than any variant, so a
model learns the objects' shapes rather than their colours (issue 74, item 2;
docs/decisions/appearance.md, "Scenes that teach shape").
"""
