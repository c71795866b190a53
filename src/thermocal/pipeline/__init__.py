"""End-to-end processing of whole recordings (``thermocal flight``)."""
