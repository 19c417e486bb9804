"""The built-in trial kinds, one module each.

A kind's module is imported on first use, so a worker running only synthetic tasks never loads MuJoCo.

=============  ======================================================================
kind           trial
=============  ======================================================================
synthetic      cheap deterministic trial (:mod:`.synthetic`): tests, overhead
grasp          lift-and-shake grasp trial, Table 6.2 (:mod:`.grasp`)
insertion      peg-in-hole insertion with the LR Mate, Ch. 5 (:mod:`.insertion`)
grinding       learned grinding force reproduction, Fig. 5.13 (:mod:`.grinding`)
guidance       guidance scenario with a simulated operator, Table 4.1 (:mod:`.guidance`)
planning       one FRMP planning problem, Ch. 7 (:mod:`.planning`)
program        a task program checked and run on its simulated cell (:mod:`.program`)
=============  ======================================================================

Each module exposes ``KIND``, a :class:`robointel.batch.registry.TrialKind`.
"""

BUILTIN = {name: f"robointel.batch.kinds.{name}"
           for name in ("synthetic", "grasp", "insertion", "grinding", "guidance", "planning",
                                                                 "program")}
