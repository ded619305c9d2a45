0 BEGIN PGM DRILLING MM
1 ; urdfpost: machine dmu50, TCP (the control keeps the tool tip on the path), mm
2 ; work offset: preset 1; program zero at 15.000 -10.000 110.000 mm on c_table
3 ; tools: T3
4 ; axis ranges: X10.000..30.000 Y-10.000..10.000 Z-15.000..435.000 B0.0000..0.0000 C0.0000..0.0000
5 ; tool axis: within 2 deg of the CL tool axis at singular spans, strategy cone: urdfpost verify --angle-tolerance 2
6 ; run time about 34.1 s: feed 30.9 s, rapid 2.2 s, dwell 1.0 s; without acceleration and tool changes
7 FUNCTION RESET TCPM
8 PLANE RESET STAY
9 M126
10 CYCL DEF 247 DATUM SETTING ~
  Q339=+1 ;DATUM NUMBER
11 L Z+0.000 R0 FMAX M91
12 ; DRILLING
13 TOOL CALL 3 Z S1200
14 M3
15 M8
16 CYCL DEF 32.0 TOLERANCE
17 CYCL DEF 32.1 T0.01
18 CYCL DEF 32.2 HSC-MODE:0 TA0.5
19 L B+0.0000 C+0.0000 FMAX
20 FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS
21 L X+10.000 Y+10.000 Z+435.000 FMAX
22 L Z+40.000 FMAX
23 L Z+30.000 B+0.0000 C+0.0000 FMAX
24 ; cycle drill
25 ; urdfpost cycle drill
26 L Z+10.000 FMAX
27 L Z+2.000 FMAX
28 L Z-6.000 F150
29 CYCL DEF 9.0 DWELL TIME
30 CYCL DEF 9.1 DWELL 0.5
31 L Z+10.000 FMAX
32 ; urdfpost cycle end
33 ; urdfpost cycle drill
34 L X+30.000 FMAX
35 L Z+2.000 FMAX
36 L Z-6.000
37 CYCL DEF 9.0 DWELL TIME
38 CYCL DEF 9.1 DWELL 0.5
39 L Z+10.000 FMAX
40 ; urdfpost cycle end
41 ; cycle deep
42 ; urdfpost cycle deep
43 L Y-10.000 Z+2.000 FMAX
44 L Z-6.000 F90
45 L Z+2.000 FMAX
46 L Z-5.746 FMAX
47 L Z-11.000
48 L Z+2.000 FMAX
49 L Z-10.746 FMAX
50 L Z-15.000
51 L Z+2.000 FMAX
52 ; urdfpost cycle end
53 ; urdfpost cycle deep
54 L X+10.000 FMAX
55 L Z-6.000
56 L Z+2.000 FMAX
57 L Z-5.746 FMAX
58 L Z-11.000
59 L Z+2.000 FMAX
60 L Z-10.746 FMAX
61 L Z-15.000
62 L Z+2.000 FMAX
63 ; urdfpost cycle end
64 ; cycle tap
65 ; urdfpost cycle tap
66 L X+20.000 Y+0.000 Z+4.000 FMAX
67 L Z-10.000 F1500
68 M4
69 L Z+4.000
70 M3
71 L X+20.000 Y+0.000 Z+4.000 B+0.0000 C+0.0000 FMAX
72 ; urdfpost cycle end
73 L Z+30.000 FMAX
74 FUNCTION RESET TCPM
75 L Z+0.000 R0 FMAX M91
76 M5
77 M9
78 L B+0.0000 C+0.0000 FMAX
79 CYCL DEF 32.0 TOLERANCE
80 CYCL DEF 32.1
81 M30
82 END PGM DRILLING MM
