"""A block on an inclined plane (a contact with a circle_on_line pair and a held rotation), the model text of
the friction tests: fill in the pose, velocity, plane normal, stiffness, friction settings, extra lines and
the run's end and output step with str.format."""

SLOPE = """
gravity (0, -9.81 m/s^2)
body block {{ mass = 1 kg  inertia = 1e-3 kg*m^2  position = ({x0}, {y0})  velocity = ({vx}, {vy})
              shape = circle(10 mm) }}
driver hold = rotation(block, speed = 0 rad/s)
joint plane = contact(ground (0, 0), block) {{
    shape = circle_on_line  normal = ({nx}, {ny})  radius = 10 mm
    law = kelvin_voigt  stiffness = {K} N/m  restitution = 0.5  {friction}
}}
{extra}
simulate {{ t_end = {t_end} s  output_step = {dt} s }}
"""
