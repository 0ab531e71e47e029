"""Studies built on the layers: the woven-fabric benchmark."""
