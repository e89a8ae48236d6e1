"""walks"""
