"""The object values of an emulated drive: what was written, the live values the drive
updates every period, and the dictionary's defaults for the rest."""

from __future__ import annotations

from canopen.objectdictionary import ObjectDictionary

from drivers.profiles import ObjectRef


class ObjectStore:
    """Values by ``(index, subindex)`` over a canopen object dictionary (its defaults)."""

    def __init__(self, dictionary: ObjectDictionary):
        self.dictionary = dictionary
        self.values: dict[tuple[int, int], object] = {}

    def get(self, index: int, subindex: int = 0):
        """Current value of an object (written value, live value or default)."""
        try:
            return self.values[(index, subindex)]
        except KeyError:
            value = self.dictionary.get_variable(index, subindex).default
            self.values[(index, subindex)] = value
            return value

    def __getitem__(self, ref: ObjectRef):
        """The value of a profile object (``store[profile.statusword]``)."""
        return self.get(ref.index, ref.subindex)

    def __setitem__(self, ref: ObjectRef, value) -> None:
        self.values[(ref.index, ref.subindex)] = value

    def optional(self, index: int, subindex: int = 0, default=0):
        """Value of an object this drive may lack (PDO sub-index 5 and 0x1006 exist on an EPOS2,
        not on an EPOS4): ``default`` where its dictionary has no such object."""
        if self.dictionary.get_variable(index, subindex) is None:
            return default
        return self.get(index, subindex)

    def has(self, index: int, subindex: int = 0) -> bool:
        return self.dictionary.get_variable(index, subindex) is not None
