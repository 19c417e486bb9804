"""Part II (Ch. 5-6): demonstrations, DTW, action decomposition, GMM/GMR skills, insertion and grinding; grasp/ for grasp transfer.

Chapter 5 modules (import them directly; nothing heavy is imported here):

* :mod:`~robointel.learning.demonstration` - :class:`Demonstration` (t, tool pose, wrench, labels).
* :mod:`~robointel.learning.datasets` - LASA handwriting and UCI robot-failure F/T loaders.
* :mod:`~robointel.learning.dtw` - numba DTW (5.1)-(5.6): ``dtw_distance``, ``dtw``, ``align``, ``warp_to``.
* :mod:`~robointel.learning.decomposition` - Algorithm 1 (5.7)-(5.13): ``ActionSegmenter``.
* :mod:`~robointel.learning.gmr` - GMM (scikit-learn) + GMR (5.14)-(5.17): ``GaussianMixtureRegression``.
* :mod:`~robointel.learning.hdd` - the hand-held demonstration device and its tool in MuJoCo.
* :mod:`~robointel.learning.insertion` - tight peg-in-hole (a package: task, device scene, scripted
  demonstrator, skill, baseline policies, impedance, robot cell, press test).
* :mod:`~robointel.learning.grinding` - plate grinding: position -> force skill, force-controlled reproduction.
* :mod:`~robointel.learning.rltt` - the pipeline (synchronise, decompose, learn).
* :mod:`~robointel.learning.ft_features` - F/T episode features for failure classification.
* :mod:`~robointel.learning.peer_checks` - DTW and GMR side by side with dtaidistance and gmr.
"""
