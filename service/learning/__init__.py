"""The room that learns: self-labels from people walking (:mod:`service.learning.labels`,
:mod:`service.learning.store`, :mod:`service.learning.listener`), and models refitted on them in
the background, served only when they are no worse (:mod:`service.learning.gate`,
:mod:`service.learning.improve`). Docs: ``docs/concepts/learning-room.md``."""
