"""Behaviour trees: movement primitives and skill templates as py_trees leaves, tree files, the runner."""
