"""The import description, ``dic.toml`` (docs/dic.md): read and checked key by key, each error
naming the key (:mod:`.spec`), table by table (:mod:`.sections`)."""
