"""Self-calibration of a three-axis hybrid INS: the physics, the estimator and the analyser.

The subpackages, bottom up (each imports only from the rows above it in this list, checked by
``tests/test_architecture.py``; each ``__init__`` names what it offers):

===============  ==================================================================================
``errors``       the one error type a user sees (what, where, how to fix)
``io``           atomic writes and hashes, one validator for TOML fields, what kind a file is
``model``        the 21 parameters, the error model, optional terms, requirements, information rules
``noise``        noise profiles, the whitening filter, Gauss-Markov filter and smoother, wander
``nav``          Earth, site, rotations, strapdown, the Jacobian (casadi), one navigation pass
``sequence``     a gimbal sequence, its rate profiles and exact kinematics, where a run turns
``gimbal``       the gimbal, the rule that plays each flip (and gimbal lock), encoder angles
``runlog``       the run-log format ``imu-run/1`` and the loggers' files: reading, writing, clock
``allan``        Allan deviation, noise terms, a noise profile fitted from a static log
``analysis``     a sequence's information over the mounting box, worst case, observability, bounds
``fit``          the estimator of a gimbal run (in memory, chunk by chunk), its step, start, checks
``sim``          the simulator of gimbal runs, streamed to disk, truth files, setup mistakes
``hand``         runs placed by hand: plans, simulator, rests, the joint fit, its weights and checks
``calibration``  the one ``calibrate`` entry, the result object, the correction a user applies
``peers``        imu_tk's method, other tools' published results, tool-free scores
===============  ==================================================================================

Data shipped with the package: ``calib/data`` (the paper's tables, the noise profiles, the
requirement classes). The library calls behind the commands are
:func:`calib.calibration.calibrate`, :func:`seqdesign.analysis.analyze` and
:func:`seqdesign.search.design_budgets`; ``seqdesign.api`` gathers them for a notebook.
"""
