"""Attachments: cloth masses held by a rigid body follow it exactly (§4, step 5)."""
from __future__ import annotations

import numba as nb


@nb.njit(cache=True, fastmath=False)
def apply_attachments(attachment_particle, attachment_body, attachment_offset_m, body_position_m, body_rotation,
                      particle_inv_mass, particle_position_m_out):
    """x_p = c_body + R_body offset for every held particle (one that let go has a mass again: skipped)."""
    for k in range(attachment_particle.shape[0]):
        p = attachment_particle[k]
        if particle_inv_mass[p] != 0.0:
            continue
        b = attachment_body[k]
        for d in range(3):
            particle_position_m_out[p, d] = (body_position_m[b, d]
                                         + body_rotation[b, d, 0] * attachment_offset_m[k, 0]
                                         + body_rotation[b, d, 1] * attachment_offset_m[k, 1]
                                         + body_rotation[b, d, 2] * attachment_offset_m[k, 2])
