"""The learners: the data equation's moments and regression, the one policy-iteration
driver, the continuous ADP learners (plain, regulator, servo), the discrete-time ADP
learner, and identify-then-design; each returns a
:class:`~selftune.learn.LearnedController`."""
