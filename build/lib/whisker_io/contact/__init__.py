"""From a whisk record to a contact: contact detection on the deflection signal
(Sec 5.1.1.1.1) and the per-contact features used by the radial-distance models."""
