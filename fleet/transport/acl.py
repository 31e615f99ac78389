"""Zenoh's `access_control` configuration from the fleet's access policy.

`fleet.mission.access` says who may do what; this writes it the way a Zenoh 1.x router
reads it: one rule per grant, one subject per identity (matched by the common name of
the certificate it presented over mutual TLS), one policy tying them, and
`default_permission: deny` for everything else.
"""

from __future__ import annotations

from typing import Any

from fleet.mission.access import Grant


def _subject_id(identity: str) -> str:
    return f"cn-{identity}"


def access_control(grants: list[Grant]) -> dict[str, Any]:
    """The `access_control` section enforcing `grants`, denying everything else."""
    identities = sorted({subject for grant in grants for subject in grant.subjects})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {
                "id": grant.name,
                "permission": "allow",
                "flows": [str(flow) for flow in grant.flows],
                "messages": [str(message) for message in grant.messages],
                "key_exprs": list(grant.key_exprs),
            }
            for grant in grants
        ],
        "subjects": [
            {"id": _subject_id(identity), "cert_common_names": [identity]}
            for identity in identities
        ],
        "policies": [
            {
                "id": f"{grant.name}-policy",
                "rules": [grant.name],
                "subjects": [_subject_id(subject) for subject in grant.subjects],
            }
            for grant in grants
        ],
    }
