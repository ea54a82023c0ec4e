"""Several spacecraft in one study (Vicariotto 2023 ch. 5): the client as a second free-flyer, the passive
(locked/shape) decomposition, the two-body plant, relative laws, capture through a compliant interface."""
