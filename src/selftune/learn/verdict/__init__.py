"""The verdict on a learned controller: standard errors from the model, the noise, the
stability margin on every plant the data allow, and the refusals when the data do not
support it (:class:`~selftune.learn.Quality`)."""
