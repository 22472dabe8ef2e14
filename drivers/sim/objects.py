"""The object values of an emulated drive: what was written, the live values the drive
updates every period, and the dictionary's defaults for the rest."""

from __future__ import annotations

from canopen.objectdictionary import ObjectDictionary

from drivers.profiles import ObjectRef, find_variable


class ObjectStore:
    """Values by ``(index, subindex)`` over a canopen object dictionary (its defaults)."""

    def __init__(self, dictionary: ObjectDictionary):
        self.dictionary = dictionary
        self.values: dict[tuple[int, int], object] = {}
        self._defined: dict[tuple[int, int], bool] = {}   # has()'s answers (the dictionary is fixed)

    def get(self, index: int, subindex: int = 0):
        """Current value of an object (written value, live value or default)."""
        try:
            return self.values[(index, subindex)]
        except KeyError:
            variable = find_variable(self.dictionary, index, subindex)
            if variable is None:
                raise KeyError(f"0x{index:04X}:{subindex:02X} is not in the drive's object dictionary") from None
            value = variable.default
            self.values[(index, subindex)] = value
            return value

    def __getitem__(self, ref: ObjectRef):
        """The value of a profile object (``store[profile.statusword]``)."""
        try:
            return self.values[ref.key]
        except KeyError:
            return self.get(ref.index, ref.subindex)

    def __setitem__(self, ref: ObjectRef, value) -> None:
        self.values[ref.key] = value

    def optional(self, index: int, subindex: int = 0, default=0):
        """Value of an object this drive may lack (e.g. the PDO event timer, sub-index 5 of the
        PDO parameters, which neither EPOS has): ``default`` where its dictionary has no such object."""
        if not self.has(index, subindex):
            return default
        return self.get(index, subindex)

    def has(self, index: int, subindex: int = 0) -> bool:
        """The dictionary defines ``index:subindex`` (a sub-index an array lacks is absent)."""
        try:
            return self._defined[(index, subindex)]
        except KeyError:
            defined = self._defined[(index, subindex)] = find_variable(self.dictionary, index, subindex) is not None
            return defined
