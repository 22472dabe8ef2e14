"""ident_hw: dynamic parameter identification of the 3PRRR parallel robot over CANopen."""

__version__ = "0.1.0"
