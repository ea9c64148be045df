"""The integrators by name, and the choices each accepts (scene files check against these)."""

#: Integrator names, as scene files and the command line give them.
INTEGRATORS = ("moreau_jean", "event_driven", "compliant")
#: The solve_ivp methods each smooth integrator accepts: explicit Runge–Kutta between the
#: events of event_driven, stiff methods for the contact springs of compliant.
IVP_METHODS = {"event_driven": ("DOP853", "RK45"), "compliant": ("Radau", "BDF", "LSODA")}
#: The contact force laws of compliant.
CONTACT_MODELS = ("linear", "hunt_crossley", "hunt_crossley_exact", "kuwabara_kono", "walton_braun")
#: Impact laws of event_driven: the generalized Newton law, Liu–Zhao–Brogliato's energetic
#: multiple-impact law (:mod:`ucontrol.integrators.lzb_impact`), and Poisson's or Stronge's
#: energetic law at a single contact (:mod:`ucontrol.integrators.frictional_impact`; the
#: energetic law passes simultaneous impacts to LZB's).
IMPACT_LAWS = ("newton", "lzb", "poisson", "energetic")
#: Restitution laws of one contact (:mod:`ucontrol.integrators.frictional_impact`); a scene may
#: give one per constraint.
RESTITUTION_LAWS = ("newton", "poisson", "energetic")
