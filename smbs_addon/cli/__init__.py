"""The command line, ``python -m smbs_addon``: its commands, arguments and exit codes (main).
"""
