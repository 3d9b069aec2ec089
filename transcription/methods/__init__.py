"""The methods of the method layer, each an implementation of :class:`~transcription.methods.base.Method`:
:mod:`.direct` (multiple-shooting NLP), :mod:`.indirect` (shooting on the discrete necessary conditions),
:mod:`.impulsive` (impulses at both ends).  The registry that picks one is :mod:`transcription.solve`."""
