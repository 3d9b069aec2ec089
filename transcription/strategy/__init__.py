"""strategy"""
# the direct method first (interim, until its solve no longer imports the strategies: methods.direct.solve imports
# the fuel strategies, which import methods.direct.solution)
from ..methods import direct as _direct  # noqa: F401  (pyflakes: used for its import)
_direct.DIRECT  # noqa: B018
