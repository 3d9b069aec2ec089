"""Strategies: combinators over one method solve (:mod:`.core`), the starts they make (:mod:`.starts`), refinement to a
tolerance (:mod:`.refine`, :mod:`.mesh`) and what to try after a failure (:mod:`.hints`)."""
