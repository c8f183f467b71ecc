/* thesis table 7.3 (figure 3): a small opaque sphere partly blocks the light
   on its way to the glass sphere 2, whose secondary source is non-full.
   Colours in 0-255 as printed in the thesis (any colour value above 1
   makes the whole file 0-255). */

V 200 200        /* viewport size in pixels: width height */
C 6 10 4         /* camera position */
A 0.5 3 0        /* target point the camera looks at */
U 0 1 0          /* camera up vector */
B 37 37          /* camera opening angles in degrees: horizontal vertical */

L 1              /* number of lights */
C 100 0 0        /* light colour r g b */
P 4 13 4         /* light position */
I 1              /* brightness */

O 3              /* number of objects */

/* sphere 1: small black opaque sphere (the obstacle) */
T 0              /* object type: 0 sphere */
C 1.5 7 2        /* sphere centre */
R 0.25           /* sphere radius */
S                /* surface definition follows */
#C 0 0 0         /* surface colour r g b */
#A 0.2           /* ka  ambient coefficient */
#D 0.4           /* kd  diffuse coefficient */
#S 0.4           /* ks  specular (and global reflection) coefficient */
#T 0             /* kt  transmission coefficient (0 = opaque) */
#E 80            /* Phong exponent */
#N 1.0           /* index of refraction */

/* sphere 2: glass lens */
T 0
C 1 6 2
R 1
S
#C 100 100 100
#A 0.1
#D 0
#S 0.4
#T 0.6
#E 80
#N 1.5

/* sphere 3: grey opaque, mirror-like sphere */
T 0
C -1 0 0
R 2
S
#C 100 100 100
#A 0.2
#D 0
#S 0.8
#T 0
#E 70
#N 1.0
