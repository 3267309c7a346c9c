"""The run an operator accepted an agent's proposal for (``caretaker run --proposal ID``, and a
console's acceptance of a proposal to run on the habitat).

An operator accepts a proposal on a console (:mod:`console.proposals`); the run then starts as any
run does, on the ground or on the habitat. Whoever sets the run up (the runner, or the console
that hands an onboard unit to a supervisor) finds the proposal in the ground database and takes it
only if it is what it is about to run: accepted by this user, of this procedure's released
version, for this binding, and not yet started. Taking it writes the run's id into the proposal in
the same conditioned UPDATE, so one acceptance starts one run, however often a start is tried
with it. The proposal's values go with the run as ``--set`` values do, and its ``run_started``
names the proposal and the agent.
"""

from __future__ import annotations

from pride.accepted_proposal import AcceptedProposal
from pride.run_setup import RunSetup
from records.agent_proposals import ProposalStore
from records.audit_log import AuditLog

__all__ = ["ProposalNotRunnable", "proposal_taken"]


class ProposalNotRunnable(Exception):
    """The proposal is not one this run may answer: the message says why."""


def proposal_taken(
    proposal_id: int | None, audit: AuditLog, user: str, setup: RunSetup, values: dict[str, str]
) -> AcceptedProposal | None:
    """Take accepted proposal ``proposal_id`` (None: the run answers none) for the run ``setup``
    prepares, adding its values to ``values`` (a value given both ways must agree).

    Raises:
        ProposalNotRunnable: as the module says, or the values disagree.
    """
    if proposal_id is None:
        return None
    store = ProposalStore(audit.engine)
    proposal = store.get(proposal_id)
    if proposal is None:
        raise ProposalNotRunnable(f"no proposal {proposal_id} in the ground database")
    proposed = proposal.proposed
    if proposal.state != "accepted" or proposal.closed_by != user:
        raise ProposalNotRunnable(
            f"proposal {proposal_id} is {proposal.state}"
            + (f" by {proposal.closed_by}" if proposal.closed_by else "")
            + f": only the operator who accepted it ({user} has not) starts its run"
        )
    if proposal.run_id is not None:
        raise ProposalNotRunnable(f"proposal {proposal_id} started run {proposal.run_id} already")
    checked = setup.checked.procedure
    version = setup.version
    if proposed.procedure != checked.id or version is None or version.sha256 != proposed.sha256:
        raise ProposalNotRunnable(
            f"proposal {proposal_id} is of {proposed.procedure} sha256 {proposed.sha256[:12]}, "
            f"not of this file ({checked.id} sha256 {(version.sha256 if version else 'unreleased')[:12]})"
        )
    binding = setup.side.binding.name
    if proposed.binding != binding:
        raise ProposalNotRunnable(f"proposal {proposal_id} is for binding {proposed.binding}, not {binding}")
    for name, value in proposed.inputs.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        if values.setdefault(name, text) != text:
            raise ProposalNotRunnable(f"--set {name}={values[name]} disagrees with proposal {proposal_id}'s {text!r}")
    if not store.started(proposal_id, user, setup.run_id):
        raise ProposalNotRunnable(f"proposal {proposal_id} was taken by another run meanwhile")
    return AcceptedProposal(proposal.id, proposed.agent, proposed.reason)
