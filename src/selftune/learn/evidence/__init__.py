"""What the data say before any controller is learned: the exact discrete model, the
alignment of the logged inputs, the dead-time model, the output-error fit and its noise,
and the consistency tests (:func:`~selftune.learn.gather_evidence`)."""
