"""What every besman package uses and that is no skill: errors (:mod:`~besman.core.errors`), argument checks
(:mod:`~besman.core.validation`), safe files (:mod:`~besman.core.reading`, :mod:`~besman.core.storage`), one
writer per output (:mod:`~besman.core.writer_lock`), seeds handed on (:mod:`~besman.core.seeds`), lazy
package names (:mod:`~besman.core.lazy`), plugins (:mod:`~besman.core.plugins`) and the old names of modules
that moved (:mod:`~besman.core.moved`).

Imports nothing else of besman's, so every besman package may use it.
"""
