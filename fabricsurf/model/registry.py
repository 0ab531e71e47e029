"""The registry of effects: every name that ``--terms``, ``--params``, diagnose candidates and
``fabricsurf terms`` accept, the built-ins and the effects a user registered in this process.

:data:`fabricsurf.model.terms.EFFECTS` is the one registry; it reads as a mapping name → Term
class (in vocabulary order, the user's effects after the built-ins), so every lookup in the
package finds a user's effect as it finds a built-in. Registering is explicit (no import of the
package registers anything): :func:`fabricsurf.model.user_effects.register_effect`, or
``--effects FILE.py`` on the command line, which check a user's class first (linear in its
moduli, a unit for each) and then call :meth:`EffectRegistry.register`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping

from fabricsurf.model.term import Term

BUILTIN = "fabricsurf"
"""The origin of the built-in effects (a user's effect: the file or module it came from)."""


class EffectRegistry(Mapping):
    """Name → Term class, with the origin of each (:data:`BUILTIN` or the user's file)."""

    def __init__(self, builtins: Iterable[type[Term]]) -> None:
        self._classes: dict[str, type[Term]] = {}
        self._origins: dict[str, str] = {}
        for cls in builtins:
            self.register(cls, BUILTIN)

    def __getitem__(self, name: str) -> type[Term]:
        return self._classes[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._classes)

    def __len__(self) -> int:
        return len(self._classes)

    def __repr__(self) -> str:
        return f"EffectRegistry({', '.join(self._classes)})"

    def register(self, cls: type[Term], origin: str) -> type[Term]:
        """Add ``cls`` under its ``name``; a name already taken (by a built-in or another
        registration) is refused with both origins, even for the same class: registering is
        done once per process, and a second time is a mistake worth a word."""
        if not (isinstance(cls, type) and issubclass(cls, Term)):
            raise ValueError(f"{origin}: {cls!r} is not a subclass of fabricsurf's Term")
        name = cls.name
        if not (isinstance(name, str) and name.isidentifier()):
            raise ValueError(
                f"{origin}: effect {cls.__name__} has name {name!r}; give it "
                "a name that is an identifier, e.g. name: ClassVar[str] = "
                '"shear_tension"'
            )
        if name in self._classes:
            other = self._origins[name]
            what = "a built-in effect" if other == BUILTIN else f"the effect from {other}"
            raise ValueError(
                f"{origin}: effect name '{name}' ({cls.__name__}) is already "
                f"taken by {what}; rename it"
            )
        self._classes[name] = cls
        self._origins[name] = origin
        return cls

    def lookup(self, name: str) -> type[Term]:
        """The class of effect ``name``; an unknown name lists the valid ones."""
        if name not in self._classes:
            raise ValueError(f"unknown term '{name}'; valid terms are: {', '.join(self)}")
        return self._classes[name]

    def origin(self, name: str) -> str:
        """Where effect ``name`` comes from: :data:`BUILTIN` or the user's file/module."""
        return self._origins[name]

    def user_effects(self) -> list[str]:
        """The names registered by the user, in registration order."""
        return [n for n, o in self._origins.items() if o != BUILTIN]

    def unregister(self, name: str) -> None:
        """Remove a user's effect (a built-in cannot be removed); for tests and notebooks
        that register a corrected version of the same effect."""
        if self._origins.get(name, BUILTIN) == BUILTIN:
            raise ValueError(f"'{name}' is not a user's effect; only those can be unregistered")
        del self._classes[name], self._origins[name]
