"""Pictures shared by the envs and the experiments (matplotlib; imports only the engine).

``tooth_row``: the tooth row's crowns coloured by coverage, with the bristles, and the buccal
coverage map (ToothRow-v0's ``render``, the tooth-row experiment's coverage.png).
"""
