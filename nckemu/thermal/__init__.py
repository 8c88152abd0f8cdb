"""Thermal compensation: recordings, models, discovery of missing physics, the fleet.

Parts, top to bottom (``.importlinter`` holds the direction): ``commands`` (``simulate``,
``discover``) > ``fleet`` > ``discovery`` | ``synthetic`` > ``model`` > ``recordings`` > ``stats``
(the shared numerics: RMS, least squares, folds, autocorrelation).
"""
