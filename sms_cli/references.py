"""The theses whose models, scenarios and published numbers sms reproduces, cited by author and
year in help, mission files and reports; ``cited`` lists the ones a text names, with their titles."""

from __future__ import annotations

import re

#: Author and year → title (and where the work was done), as the report's references list them.
THESES: dict[str, str] = {
    "Caldera 2019": "Sliding Mode Attitude Control for Small Satellite with Manipulator",
    "Chevallard 2019": "Mission Design and Modeling of Space Manipulators for In-Orbit Servicing Missions",
    "Vicariotto 2023": "A Momentum-based Relative Dynamics Model for Hardware-in-the-Loop Simulation of On-Orbit Servicing",
    "Ruggiero 2020": "Robust attitude control for NASA Astrobee robots operating in the ISS",
    "Kraiem 2022": "Development of steering law for On Orbit Servicing operation (PhD thesis, ISAE/ONERA, HAL tel-04117430)",
}


def cited(text: str) -> list[tuple[str, str]]:
    """(author year, title) of each thesis ``text`` names ("Caldera 2019" or "Caldera (2019)"), in list order."""
    out = []
    for key, title in THESES.items():
        author, year = key.split()
        if re.search(rf"\b{author} \(?{year}\b", text):
            out.append((key, title))
    return out
