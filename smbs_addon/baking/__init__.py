"""baking"""
