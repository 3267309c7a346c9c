"""The habitat's command ledger: each command key executes at most once, and its outcome is kept.

``caretaker ledger --state-dir DIR`` (:mod:`bridge.ledger.main`); the node is
:class:`bridge.ledger.node.LedgerNode`, its memory :class:`bridge.ledger.store.LedgerStore`.
"""
